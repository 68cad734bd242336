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
