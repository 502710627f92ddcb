#!/usr/bin/env python3
"""Every subcommand's --help (subcommands of subcommands too, e.g. `rig run`) exits 0, and every option it lists is accepted by the parser
(`pamc --parse-only CMD OPTION VALUE` exits 0), with a value taken from the help text itself: the
default, the first allowed choice, or the lower end of a range. Prints one line per failure."""
import re
import subprocess
import sys

pamc = sys.argv[1]
fails = 0
checked = 0
top = subprocess.run([pamc, "--help"], capture_output=True, text=True)
if top.returncode != 0:
    print("FAIL: pamc --help exits", top.returncode)
    sys.exit(1)
commands = re.findall(r"^  ([a-z][a-z-]*)\s{2,}", top.stdout.split("Subcommands:")[1], re.M)
if len(commands) < 10:
    print("FAIL: pamc --help lists only", commands)
    sys.exit(1)
commands = [[c] for c in commands]
for cmd in commands:
    h = subprocess.run([pamc] + cmd + ["--help"], capture_output=True, text=True)
    if h.returncode != 0 or "Usage:" not in h.stdout:
        print(f"FAIL: pamc {' '.join(cmd)} --help exits {h.returncode}")
        fails += 1
        continue
    text = h.stdout
    if "Subcommands:" in text:
        commands += [cmd + [s] for s in re.findall(r"^  ([a-z][a-z-]*)\s{2,}", text.split("Subcommands:")[1], re.M)]
    # Required positionals get a placeholder (nothing runs).
    positionals = []
    if "Positionals:" in text:
        block = text.split("Positionals:")[1].split("Options:")[0]
        for name, kind in re.findall(r"^  ([a-z_]+) (TEXT|FLOAT|INT|UINT)\S* REQUIRED", block, re.M):
            positionals.append("x" if kind == "TEXT" else "1")
    opts = text.split("Options:")[1] if "Options:" in text else ""
    # Required options go into every invocation.
    for m in re.finditer(r"^  (--[a-z0-9-]+) (TEXT|FLOAT|INT|UINT)\S* REQUIRED", opts, re.M):
        positionals += [m.group(1), "x" if m.group(2) == "TEXT" else "1"]
    for m in re.finditer(r"^  (-\w,)?(--[a-z0-9-]+)(?:,--[a-z0-9-]+)*( [A-Z]+[^ \n]*)?(.*)$", opts, re.M):
        name, typ, rest = m.group(2), (m.group(3) or "").strip(), m.group(4)
        if name == "--help" or name in positionals:
            continue
        args = [name]
        if typ:
            choice = re.search(r"\{([^}]*)\}", typ)
            default = re.search(r"=(\S+)", typ)
            rng = re.search(r"in \[([-0-9.e]+) - ", typ + rest)
            if choice:
                args.append(choice.group(1).split(",")[0])
            elif default:
                args.append(default.group(1))
            elif rng:
                args.append(rng.group(1))
            elif typ.startswith(("FLOAT", "INT", "UINT")):
                args.append("1")
            else:
                args.append("x")
        needs = re.search(r"Needs: (--[a-z-]+)", rest)
        if needs:
            args.append(needs.group(1))
        r = subprocess.run([pamc, "--parse-only"] + cmd + positionals + args, capture_output=True, text=True)
        checked += 1
        if r.returncode != 0:
            print(f"FAIL: pamc {' '.join(cmd)} {' '.join(positionals + args)}: exit {r.returncode}: {r.stderr.strip().splitlines()[0] if r.stderr.strip() else ''}")
            fails += 1
print(f"{len(commands)} subcommands, {checked} options accepted as their help lists them, {fails} failures")
sys.exit(1 if fails or checked < 50 else 0)
