"""The compiled half of the Python package's build (pyproject.toml has the metadata).

setuptools copies the pure-Python files of python/lgvi; `build_py` below also builds the extension
module lgvi._core with CMake (target lgvi_python of src/python/CMakeLists.txt, which links the same
run library as the command-line tool, so that Python and `lgvi run` give bit-identical results) and
puts it next to them, with three.js for lgvi.view when web/node_modules has it.

Environment:
  LGVI_CMAKE_BUILD_DIR  an existing CMake build tree of this source to take lgvi._core from (built
                        there with `cmake --build DIR --target lgvi_python`; nothing is recompiled
                        when it is up to date). Without it, a Release tree is configured for the
                        running interpreter (tests, benchmarks and MPI off) in the build's
                        temporary folder.
  CMAKE_BUILD_PARALLEL_LEVEL  compile jobs (default: the number of processors).

setuptools' own folders (build/, the egg-info) go to a new temporary folder on every invocation,
removed at exit: nothing of an earlier build (another interpreter's module, a file since removed)
can reach a wheel, and two builds at once do not share one. pybind11's CMake package comes from
the system (Debian's pybind11-dev); where the Python package pybind11 is importable instead (a
PyPI-style build environment), its CMake directory is passed to CMake.
"""

import atexit
import os
import pathlib
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

ROOT = pathlib.Path(__file__).resolve().parent
WORK = pathlib.Path(tempfile.mkdtemp(prefix="lgvi-setuptools-"))  # setuptools' build/ and egg-info (the docstring)
atexit.register(shutil.rmtree, WORK, ignore_errors=True)
# lgvi.view's three.js (MIT, web/package-lock.json), copied into the wheel under lgvi/_three/ with the
# same relative paths as in node_modules/three (python/lgvi/viewer.py reads them from either place).
THREE_FILES = ("LICENSE", "build/three.module.js", "build/three.core.js", "examples/jsm/controls/OrbitControls.js")


def cmake_version():
    """The project's version, from CMakeLists.txt's project() call."""
    text = (ROOT / "CMakeLists.txt").read_text(encoding="utf-8")
    match = re.search(r"project\(lgvi VERSION (\d+\.\d+\.\d+)", text)
    if match is None:
        raise RuntimeError("setup.py: CMakeLists.txt has no `project(lgvi VERSION x.y.z ...)`")
    return match.group(1)


class BinaryDistribution(Distribution):
    """A wheel for this interpreter and platform (it holds a compiled module), not a pure-Python one."""

    def has_ext_modules(self):
        return True


def run(command):
    print("lgvi build:", " ".join(str(c) for c in command), flush=True)
    subprocess.run([str(c) for c in command], check=True)


def build_core(build_temp):
    """Path of lgvi/_core<EXT_SUFFIX> built by CMake for this interpreter."""
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    given = os.environ.get("LGVI_CMAKE_BUILD_DIR")
    if given:
        tree = pathlib.Path(given).resolve()
        if not (tree / "CMakeCache.txt").is_file():
            raise RuntimeError(f"LGVI_CMAKE_BUILD_DIR={given}: not a configured CMake build tree "
                               "(no CMakeCache.txt); unset it to build one, or run scripts/setup.sh first")
    else:
        tree = pathlib.Path(build_temp).resolve() / "cmake"
        hints = []
        try:
            import pybind11  # noqa: PLC0415 (only where pip installed it)
            hints.append(f"-Dpybind11_DIR={pybind11.get_cmake_dir()}")
        except ImportError:
            pass
        run(["cmake", "-S", ROOT, "-B", tree, "-DCMAKE_BUILD_TYPE=Release", "-DLGVI_BUILD_TESTS=OFF",
             "-DLGVI_BUILD_BENCHMARKS=OFF", "-DLGVI_MPI=OFF", f"-DLGVI_SYSTEM_PYTHON={sys.executable}", *hints])
    jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
    run(["cmake", "--build", tree, "--target", "lgvi_python", "-j", jobs])
    core = tree / "python" / "lgvi" / f"_core{suffix}"
    if not core.is_file():
        found = sorted(p.name for p in (tree / "python" / "lgvi").glob("_core*.so"))
        raise RuntimeError(f"{tree}: no {core.name} for this interpreter ({sys.executable}, "
                           f"found {found or 'none'}); the tree was configured for another Python: "
                           "build one for this interpreter (unset LGVI_CMAKE_BUILD_DIR)")
    return core


class BuildPyWithCore(build_py):
    """build_py, then lgvi._core and three.js into the same package folder."""

    def run(self):
        super().run()
        package = pathlib.Path(self.build_lib) / "lgvi"
        core = build_core(self.get_finalized_command("build").build_temp)
        shutil.copy2(core, package / core.name)
        three = ROOT / "web" / "node_modules" / "three"
        if all((three / f).is_file() for f in THREE_FILES):
            for f in THREE_FILES:
                (package / "_three" / f).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(three / f, package / "_three" / f)
        else:
            print("lgvi build: warning: web/node_modules/three is missing (npm ci --prefix web): the package's "
                  "lgvi.view will ask for it", file=sys.stderr, flush=True)


setup(
    version=cmake_version(),
    distclass=BinaryDistribution,
    cmdclass={"build_py": BuildPyWithCore},
    options={"build": {"build_base": str(WORK)}, "egg_info": {"egg_base": str(WORK)}},
)
