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


def test_sweep_stubs_match_the_module():
    """pamc.sweep's stubs: the functions of __all__, with the same parameters."""
    import inspect
    import pamc.sweep
    with open(os.path.join(os.path.dirname(pamc.__file__), "sweep.pyi")) as f:
        tree = ast.parse(f.read())
    funcs = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert set(funcs) == set(pamc.sweep.__all__)
    for name, node in funcs.items():
        a = node.args
        stubbed = [x.arg for x in a.args + a.kwonlyargs] + ([a.kwarg.arg] if a.kwarg else [])
        assert stubbed == list(inspect.signature(getattr(pamc.sweep, name)).parameters), name
