"""The type stubs name what the module has, no more and no less."""
import ast
import os

import pamc


def stub_tree():
    with open(os.path.join(os.path.dirname(pamc.__file__), "__init__.pyi")) as f:
        return ast.parse(f.read())


def test_stubs_match_the_module():
    tree = stub_tree()
    top = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    assert top == set(pamc.__all__)
    for cls in (n for n in tree.body if isinstance(n, ast.ClassDef)):
        stubbed = {m.name for m in cls.body if isinstance(m, ast.FunctionDef) and not m.name.startswith("__")}
        stubbed |= {m.target.id for m in cls.body if isinstance(m, ast.AnnAssign)}
        public = {a for a in dir(getattr(pamc, cls.name)) if not a.startswith("_")}
        assert stubbed == public, cls.name
