"""docs/python.md's example runs as written (on the bundled bunny)."""

import os
import re
import subprocess
import sys

import hgdeform
from conftest import ROOT


def test_the_documented_example_runs(tmp_path):
    text = (ROOT / "docs" / "python.md").read_text()
    code = "\n".join(re.findall(r"```python\n(.*?)```", text, re.S))
    assert "hgdeform.deform" in code and "HandleDeformation" in code
    (tmp_path / "datasets").symlink_to(ROOT / "datasets")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                       env=dict(os.environ,
                                PYTHONPATH=os.path.dirname(os.path.dirname(hgdeform.__file__))))
    assert r.returncode == 0, r.stderr
    for name in ("bunny_deformed.ply", "bunny_interactive.ply"):
        assert (tmp_path / name).stat().st_size > 0, name


def _signatures():
    """(qualified name, first docstring line) of every function and method the C++ module binds."""
    mod = hgdeform._hgdeform
    out = []
    for name in dir(mod):
        obj = getattr(mod, name)
        members = [(name, obj)] if callable(obj) and not isinstance(obj, type) else []
        if isinstance(obj, type):
            members += [("%s.%s" % (name, m), getattr(obj, m)) for m in vars(obj) if not m.startswith("__")
                        or m == "__init__"]
        for qual, f in members:
            doc = getattr(f, "__doc__", None) or ""
            if "(" in doc.split("\n", 1)[0]:
                out.append((qual, doc.split("\n", 1)[0]))
    return out


def test_signatures_name_what_each_argument_takes():
    # pybind11 shows an argument taken as any object as "handle" (`center: handle`): help() and
    # IDEs must say what is expected (an array-like, a Region, a path, a scenario) instead.
    sigs = _signatures()
    assert len(sigs) > 30
    vague = [(q, s) for q, s in sigs if re.search(r":\s*(handle|object)\b", s)]
    assert not vague, vague
    frame = dict(sigs)["Scenario.frame"]
    assert "center: numpy.typing.ArrayLike | None = None" in frame, frame
    assert "path: str | os.PathLike" in dict(sigs)["read"]
