"""`pip install .` from a checkout (docs/python.md): setuptools drives the project's CMake.

build_ext configures the project in build-pip/ (HGDEFORM_PIP_BUILD_DIR to change it; the
library and the module only: no tools, no tests), builds the target _hgdeform alone, installs
it into a staging prefix and copies the module and libhgdeform.so.0 into the wheel's hgdeform/
(the module's RPATH is $ORIGIN); build_py adds __init__.py, __init__.pyi and py.typed. Compilation goes through ccache when it is installed, as
scripts/ccache.sh sets it up: the cache is keyed on paths relative to the checkout, so a build
here reuses what build/ compiled with the same options (HGDEFORM_CMAKE_ARGS adds CMake
arguments, e.g. "-DHGDEFORM_WERROR=ON" as scripts/test.sh builds; HGDEFORM_BUILD_JOBS the job
count, 2 by default).

    pip install --no-build-isolation --no-deps .
"""

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


def project_version():
    """project(hgdeform VERSION x.y.z) of CMakeLists.txt: the version `hgdeform --version` prints."""
    text = (ROOT / "CMakeLists.txt").read_text()
    m = re.search(r"project\(\s*hgdeform\b[^)]*?\bVERSION\s+([0-9][0-9.]*)", text, re.S)
    if not m:
        raise RuntimeError("CMakeLists.txt: no project(hgdeform VERSION ...)")
    return m.group(1)


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build_dir = Path(os.environ.get("HGDEFORM_PIP_BUILD_DIR") or ROOT / "build-pip").resolve()
        stage = build_dir / "wheel-stage"
        env = dict(os.environ)
        args = ["-S", str(ROOT), "-B", str(build_dir), "-DCMAKE_BUILD_TYPE=Release",
                "-DHGDEFORM_BUILD_TOOLS=OFF", "-DHGDEFORM_BUILD_TESTS=OFF", "-DHGDEFORM_PYTHON=ON",
                "-DPython3_EXECUTABLE=" + sys.executable,
                # The package's layout: the module and the library in one folder, RPATH $ORIGIN.
                "-DHGDEFORM_PYTHON_INSTALL_DIR=wheel", "-DCMAKE_INSTALL_LIBDIR=wheel/hgdeform"]
        if shutil.which("ninja") and not (build_dir / "CMakeCache.txt").exists():
            args += ["-G", "Ninja"]
        if shutil.which("ccache") and env.get("HGD_NO_CCACHE") != "1":  # as scripts/ccache.sh
            env.update(CCACHE_BASEDIR=str(ROOT), CCACHE_NOHASHDIR="1")
            args += ["-DCMAKE_CXX_COMPILER_LAUNCHER=ccache", "-DCMAKE_C_COMPILER_LAUNCHER=ccache"]
        args += shlex.split(env.get("HGDEFORM_CMAKE_ARGS", ""))
        jobs = env.get("HGDEFORM_BUILD_JOBS", "2")

        def run(*command):
            print("+ " + " ".join(map(shlex.quote, command)), flush=True)
            subprocess.run(command, check=True, env=env)

        run("cmake", *args)
        run("cmake", "--build", str(build_dir), "--target", "_hgdeform", "-j", jobs)
        shutil.rmtree(stage, ignore_errors=True)
        run("cmake", "--install", str(build_dir), "--prefix", str(stage))

        package = stage / "wheel" / "hgdeform"
        modules = sorted(package.glob("_hgdeform*.so"))
        if len(modules) != 1:
            raise RuntimeError("expected one _hgdeform module in %s, found %s" % (package, modules))
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(modules[0], target)
        # The library by its soname (what the module's DT_NEEDED names), the file the link
        # points to: a wheel has no symbolic links.
        for lib in package.glob("libhgdeform.so.*"):
            if lib.name.count(".") == 2:  # libhgdeform.so.0
                shutil.copyfile(lib.resolve(), target.parent / lib.name)


# setuptools' own build folder and metadata beside CMake's, not in build/ (the project's
# build tree) nor in the sources.
(ROOT / "build-pip").mkdir(exist_ok=True)
setup(
    options={"build": {"build_base": "build-pip/setuptools"}, "egg_info": {"egg_base": "build-pip"}},
    version=project_version(),
    packages=["hgdeform"],
    package_dir={"": "python"},
    package_data={"hgdeform": ["__init__.pyi", "py.typed"]},  # (build_py copies them)
    ext_modules=[Extension("hgdeform._hgdeform", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    zip_safe=False,
)
