#!/usr/bin/env python3
"""Data members per class and struct: the check for "no class above 20 data members" (issue 37, step 8).

Each C++ file named (a header or a source file) is parsed with clang++ (-fsyntax-only, C++17, the
repository root and src/ on the include path, more with -I); every class or struct defined in the
namespace given (nested and anonymous-namespace ones included) is counted once: its own fields, and
with those of its bases (what an object of it holds). A nested struct's members count once, as the
field that holds it.

Prints the classes above the limit (all with --all), largest first; exits 1 if any is above it, 2 on a
usage error or a file clang cannot parse.
  tools/member_count.py [--limit 20] [--all] [--namespace pamc] [-I DIR] FILE...
  tools/member_count.py --all canopen/*.hpp canopen/*.cpp
  tools/member_count.py -I /usr/include/eigen3 src/control/*.hpp
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLANG = shutil.which("clang++") or shutil.which("clang++-14")  # tools/deps.sh installs clang-14


def ast_dumps(path, namespace, includes):
    """The JSON AST of the declarations in namespace, one object per top-level match."""
    lang = ["-x", "c++", "-Wno-pragma-once-outside-header"] if path.endswith((".hpp", ".h")) else []
    cmd = [CLANG, "-std=c++17", *("-I" + d for d in includes), "-fsyntax-only", *lang, "-Xclang", "-ast-dump=json",
           "-Xclang", "-ast-dump-filter=" + namespace, path]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        print(f"{path}: clang++ failed:\n{run.stderr}", file=sys.stderr)
        sys.exit(2)
    decoder, text, pos = json.JSONDecoder(), run.stdout, 0
    while True:
        while pos < len(text) and text[pos].isspace():
            pos += 1
        if pos >= len(text):
            return
        obj, pos = decoder.raw_decode(text, pos)
        yield obj


def collect(node, scope, records):
    """Walks node; records[qualified name] = (own field count, base type names)."""
    kind, name = node.get("kind"), node.get("name")
    if kind == "NamespaceDecl":
        scope = scope + [name or "(anonymous)"]
    elif kind == "CXXRecordDecl" and node.get("completeDefinition") and node.get("tagUsed") in ("class", "struct"):
        if name is None or node.get("isImplicit"):
            return  # an anonymous struct counts as the field holding it; the injected class name is no class
        scope = scope + [name]
        fields = sum(1 for c in node.get("inner", []) if c.get("kind") == "FieldDecl")
        bases = [b["type"]["qualType"] for b in node.get("bases", [])]
        records["::".join(scope)] = (fields, bases)
    elif kind in ("FunctionDecl", "CXXMethodDecl", "CXXConstructorDecl", "LambdaExpr"):
        return  # local classes and lambdas' closures are not the classes this check is about
    for child in node.get("inner", []):
        collect(child, scope, records)


def total(name, records, seen=()):
    """Fields of name with those of its bases (base names resolved by their last components)."""
    fields, bases = records[name]
    for base in bases:
        base = base.replace("struct ", "").replace("class ", "")
        match = [r for r in records if r == base or r.endswith("::" + base)]
        if match and match[0] not in seen:
            fields += total(match[0], records, seen + (name,))
    return fields


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--limit", type=int, default=20)
    parser.add_argument("--all", action="store_true", help="print every class, not only those above the limit")
    parser.add_argument("--namespace", default="pamc")
    parser.add_argument("-I", dest="includes", action="append", default=[ROOT, os.path.join(ROOT, "src")],
                        help="another include directory (the repository root and src/ are always searched)")
    args = parser.parse_args()
    if CLANG is None:
        parser.error("needs clang++ (tools/deps.sh installs clang-14)")
    records = {}
    for path in args.files:
        for dump in ast_dumps(path, args.namespace, args.includes):
            collect(dump, [], records)
    rows = sorted(((total(n, records), records[n][0], n) for n in records), key=lambda r: (-r[0], r[2]))
    over = [r for r in rows if r[0] > args.limit]
    print(f"{len(rows)} classes, {len(over)} above {args.limit} data members (with bases; own in brackets)")
    for held, own, name in rows if args.all else over:
        print(f"{held:4d} ({own:2d})  {name}")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
