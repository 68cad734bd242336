"""The .pyi stub parses and names what the package has (so that editors complete real names)."""

import ast
import pathlib

import hgdeform


def stub():
    return ast.parse((pathlib.Path(hgdeform.__file__).parent / "__init__.pyi").read_text())


def test_the_stub_names_every_public_name_and_no_other():
    tree = stub()
    top = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    public = set(hgdeform.__all__) - {"__version__"}
    assert public <= top, public - top
    for name in top:
        assert hasattr(hgdeform, name), name


def test_the_stubs_methods_exist():
    for node in stub().body:
        if not isinstance(node, ast.ClassDef):
            continue
        cls = getattr(hgdeform, node.name)
        for item in node.body:
            if isinstance(item, ast.FunctionDef):
                assert hasattr(cls, item.name), (node.name, item.name)
            elif isinstance(item, ast.AnnAssign):
                assert hasattr(cls, item.target.id), (node.name, item.target.id)


def _stub_names(fn):
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    if a.vararg:
        names.append("*" + a.vararg.arg)
    if a.kwarg:
        names.append("**" + a.kwarg.arg)
    return [n for n in names if n != "self"]


def _real_names(obj):
    """Parameter names of a Python function, or of a pybind11 one from its signature line."""
    import inspect
    import re

    try:
        params = inspect.signature(obj).parameters.values()
    except (TypeError, ValueError):
        doc = (getattr(obj, "__doc__", None) or "").lstrip().splitlines()
        m = re.match(r"\w+\((.*)\)\s*->", doc[0]) if doc else None
        if not m:
            return None  # an overloaded function: no single signature to compare
        parts, depth, cur = [], 0, ""
        for ch in m.group(1):  # split at the commas outside brackets (defaults, types)
            depth += ch in "([{" and 1 or (ch in ")]}" and -1 or 0)
            if ch == "," and depth == 0:
                parts.append(cur)
                cur = ""
            else:
                cur += ch
        parts.append(cur)
        names = [re.match(r"\s*(\*{0,2}\w+)", p).group(1) for p in parts if p.strip()]
        return [n for n in names if n != "self"]
    prefix = {inspect.Parameter.VAR_POSITIONAL: "*", inspect.Parameter.VAR_KEYWORD: "**"}
    return [prefix.get(p.kind, "") + p.name for p in params if p.name != "self"]


def test_the_stubs_parameter_names_are_the_modules():
    def check(where, node, real):
        decorators = [getattr(d, "id", "") for d in node.decorator_list]
        if isinstance(real, property) or "property" in decorators:
            return
        names = _real_names(real)
        if names is None:
            return
        if "overload" in decorators:  # one form: some of the parameters, by their names
            assert set(_stub_names(node)) <= set(names), (where, _stub_names(node), names)
        else:
            assert _stub_names(node) == names, where
        checked.append(where)

    checked = []
    for node in stub().body:
        if isinstance(node, ast.FunctionDef):
            check(node.name, node, getattr(hgdeform, node.name))
        elif isinstance(node, ast.ClassDef):
            cls = getattr(hgdeform, node.name)
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    check(node.name + "." + item.name, item, getattr(cls, item.name))
    for name in ("deform", "write", "HandleDeformation.drag", "HandleDeformation.__init__"):
        assert name in checked, name
