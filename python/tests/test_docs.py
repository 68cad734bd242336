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
