"""The conformance suite: files written at test time by PCL, Open3D, CloudCompare and MeshLab,
deformed by hgdeform and read back by the tool that wrote them (README.md in this folder)."""

import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

import checks  # noqa: E402


@pytest.fixture(scope="session")
def session(tmp_path_factory):
    return checks.Session(tmp_path_factory.mktemp("conformance"))
