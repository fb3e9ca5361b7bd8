"""The Python package installed the Python way (pyproject.toml + setup.py): a wheel built with Debian's
`python3 -m build --no-isolation --wheel`, installed with pip into a fresh virtual environment
(--system-site-packages, so that Debian's numpy and matplotlib serve, no index reached), used there
(a run bit-identical to the command-line tool's, a view page, the package's own test file
tests/python/test_package.py), uninstalled; and `pip install --no-build-isolation .` from the source.

Run by ctest (python.wheel) with LGVI_CMAKE_BUILD_DIR set to the test build tree, so that the wheel
takes the lgvi._core already compiled there instead of compiling it a second time (setup.py documents
the variable), and with LGVI_BINARY and LGVI_SOURCE_DIR as for the other Python tests. Every child runs
without PYTHONPATH or LGVI_SOURCE_DIR: what it imports, and lgvi.view's three.js, must come from the
virtual environment. The build a user gets, a source distribution compiled from scratch through CMake
(about 2 minutes on 2 cores), runs with LGVI_WHEEL_FROM_SCRATCH=1 (test_a_wheel_from_the_sdist_...).
"""

import email.parser
import json
import os
import pathlib
import re
import subprocess
import sys
import sysconfig
import zipfile

import pytest
from packaging.requirements import Requirement

SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
BINARY = os.environ.get("LGVI_BINARY")
if BINARY is None or "LGVI_CMAKE_BUILD_DIR" not in os.environ:
    pytest.skip("run through ctest (python.wheel): needs LGVI_BINARY and LGVI_CMAKE_BUILD_DIR", allow_module_level=True)
pytest.importorskip("build", reason="Debian's python3-build (scripts/setup.sh installs it)")


def clean_env(**extra):
    """The environment without PYTHONPATH and LGVI_SOURCE_DIR (the build tree's package, or the source tree's
    three.js, must not leak into the venv)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "LGVI_SOURCE_DIR")}
    env.update(extra)
    return env


def check(command, **kwargs):
    proc = subprocess.run([str(c) for c in command], capture_output=True, text=True, env=clean_env(), **kwargs)
    assert proc.returncode == 0, f"{command}:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc


def cmake_version():
    return re.search(r"project\(lgvi VERSION (\d+\.\d+\.\d+)", (SOURCE / "CMakeLists.txt").read_text()).group(1)


def make_venv(path):
    check([sys.executable, "-m", "venv", "--system-site-packages", path])
    return path / "bin" / "python"


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--wheel", "--outdir", str(out), str(SOURCE)],
                          capture_output=True, text=True, env=clean_env())
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    wheels = list(out.glob("*.whl"))
    assert len(wheels) == 1, wheels
    return wheels[0]


def test_wheel_holds_the_package_the_module_and_the_licence(wheel):
    version = cmake_version()
    tag = sysconfig.get_config_var("EXT_SUFFIX")  # .cpython-311-x86_64-linux-gnu.so
    # A wheel for this interpreter and platform (it holds compiled code), named by CMake's version.
    assert re.fullmatch(rf"lgvi-{re.escape(version)}-cp3\d+-cp3\d+-linux_\w+\.whl", wheel.name), wheel.name
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        meta = email.parser.Parser().parsestr(z.read(f"lgvi-{version}.dist-info/METADATA").decode())
    sources = {f"lgvi/{p.name}" for p in (SOURCE / "python" / "lgvi").iterdir()
               if p.suffix in (".py", ".pyi", ".html") or p.name == "py.typed"}
    assert sources <= names, sorted(sources - names)
    assert f"lgvi/_core{tag}" in names
    # three.js for lgvi.view (web/node_modules, npm ci --prefix web, which scripts/setup.sh runs), with its licence.
    assert {"lgvi/_three/LICENSE", "lgvi/_three/build/three.module.js", "lgvi/_three/build/three.core.js",
            "lgvi/_three/examples/jsm/controls/OrbitControls.js"} <= names
    # The build tree's pointer to its sources is not relocatable and stays out of the wheel.
    assert "lgvi/_source_dir.txt" not in names
    assert f"lgvi-{version}.dist-info/LICENSE" in names
    assert meta["Name"] == "lgvi" and meta["Version"] == version
    assert meta["License"] == "BSD-3-Clause"
    requires = {str(Requirement(r)) for r in meta.get_all("Requires-Dist")}  # normalised spelling
    assert requires == {"matplotlib>=3.5", "numpy>=1.21", 'h5py; extra == "hdf5"'}


RUN_IN_VENV = r"""
import json, pathlib, sys
import numpy as np
import lgvi
import lgvi.viewer
out = pathlib.Path(sys.argv[1])
site = pathlib.Path(sys.argv[2]).resolve()
# Imported from the virtual environment, compiled module included.
assert pathlib.Path(lgvi.__file__).resolve().is_relative_to(site), lgvi.__file__
from lgvi import _core
assert pathlib.Path(_core.__file__).resolve().is_relative_to(site), _core.__file__
scenario = lgvi.Scenario.from_toml(sys.argv[3])
result = lgvi.simulate(scenario)
np.save(out / "state.npy", np.column_stack([result.x, result.q, result.p, result.w]))
path = lgvi.view(result, out / "view.html")
three = lgvi.viewer.three_dir()                      # the wheel's own copy, not a source tree's
assert pathlib.Path(three).resolve().is_relative_to(site), three
print(json.dumps({"version": lgvi.__version__, "rows": len(result.t), "view": str(path)}))
"""


def short_paper_orbit(tmp):
    """The paper's orbit, 200 steps (the same file for the CLI and the package)."""
    text = (SOURCE / "scenarios" / "paper-orbit.toml").read_text()
    text = re.sub(r"(?m)^duration\s*=.*$", "duration = 2.0", text)
    path = tmp / "short-orbit.toml"
    path.write_text(text)
    return path


def test_installed_wheel_runs_like_the_cli_then_uninstalls(wheel, tmp_path):
    import numpy as np

    python = make_venv(tmp_path / "venv")
    check([python, "-m", "pip", "install", "--no-index", "--no-input", wheel])
    site = pathlib.Path(check([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
    scenario = short_paper_orbit(tmp_path)
    proc = check([python, "-c", RUN_IN_VENV, tmp_path, site, scenario])
    info = json.loads(proc.stdout.strip().splitlines()[-1])
    assert info["version"] == cmake_version()
    assert pathlib.Path(info["view"]).is_file()
    assert b"three/core" in pathlib.Path(info["view"]).read_bytes()  # three.js inlined (from the wheel's copy)

    # The CLI of the same build, on the same file: the installed module runs the same compiled loop, so
    # every number is equal to the last bit (its 17-digit CSV reads back exactly).
    cli_out = tmp_path / "cli"
    check([BINARY, "run", scenario, "--out", cli_out, "--no-figures", "-q"])
    header = (cli_out / "trajectory.csv").read_text().splitlines()[0].split(",")
    data = np.loadtxt(cli_out / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    cols = [header.index(c) for c in ("x", "y", "z", "qw", "qx", "qy", "qz", "px", "py", "pz", "wx", "wy", "wz")]
    state = np.load(tmp_path / "state.npy")
    assert info["rows"] == len(data) == 21  # 200 steps of h = 0.01, a row every 10 steps
    assert np.array_equal(state, data[:, cols])

    # The package's own test file, against the installed package.
    proc = subprocess.run([str(python), "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           str(SOURCE / "tests" / "python" / "test_package.py")],
                          capture_output=True, text=True, cwd=tmp_path,
                          env=clean_env(LGVI_BINARY=BINARY, LGVI_SOURCE_DIR=str(SOURCE)))
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert " passed" in proc.stdout and "skipped" not in proc.stdout.splitlines()[-1], proc.stdout[-500:]

    check([python, "-m", "pip", "uninstall", "-y", "lgvi"])
    assert not (site / "lgvi").exists()
    assert not list(site.glob("lgvi-*.dist-info"))


def test_pip_install_from_the_source_tree(tmp_path):
    python = make_venv(tmp_path / "venv")
    check([python, "-m", "pip", "install", "--no-build-isolation", "--no-index", "--no-input", SOURCE])
    proc = check([python, "-c", "import lgvi, lgvi._core; print(lgvi.__file__); print(lgvi.__version__)"],
                 cwd=tmp_path)
    file, version = proc.stdout.split()
    assert pathlib.Path(file).resolve().is_relative_to((tmp_path / "venv").resolve())
    assert version == cmake_version()


def test_the_source_distribution_carries_what_the_build_reads(tmp_path):
    out = tmp_path / "dist"
    check([sys.executable, "-m", "build", "--no-isolation", "--sdist", "--outdir", out, SOURCE])
    (sdist,) = out.glob("lgvi-*.tar.gz")
    import tarfile
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    # CMake's inputs for lgvi._core (every source of the run library and the module), the package, the licence.
    for f in ("CMakeLists.txt", "cmake/lgviConfig.cmake.in", "setup.py", "pyproject.toml", "LICENSE",
              "src/python/CMakeLists.txt", "src/python/module.cpp", "include/lgvi/lgvi.hpp", "python/lgvi/__init__.py",
              "python/lgvi/viewer.html", "web/package-lock.json"):
        assert f in names, f
    sources = set(re.findall(r"src/[\w/]+\.cpp", (SOURCE / "CMakeLists.txt").read_text()))
    assert sources and sources <= names, sorted(sources - names)
    assert not any(n.startswith(("build/", "tests/", "results/")) for n in names)


@pytest.mark.skipif(os.environ.get("LGVI_WHEEL_FROM_SCRATCH") != "1",
                    reason="compiles lgvi._core from scratch (~2 min on 2 cores): LGVI_WHEEL_FROM_SCRATCH=1")
def test_a_wheel_from_the_sdist_compiled_from_scratch(tmp_path):
    # The build a user gets: `python3 -m build --no-isolation` makes the sdist and the wheel from it, with no build
    # tree given (setup.py configures and compiles one), then the wheel runs in a fresh venv like the CLI.
    import numpy as np

    out = tmp_path / "dist"
    env = {k: v for k, v in clean_env().items() if k != "LGVI_CMAKE_BUILD_DIR"}
    proc = subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--outdir", str(out), str(SOURCE)],
                          capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "lgvi build: cmake -S" in proc.stdout  # it configured a tree of its own
    (wheel,) = out.glob("*.whl")
    python = make_venv(tmp_path / "venv")
    check([python, "-m", "pip", "install", "--no-index", "--no-input", wheel])
    scenario = short_paper_orbit(tmp_path)
    code = ("import sys, numpy as np, lgvi; r = lgvi.simulate(lgvi.Scenario.from_toml(sys.argv[1])); "
            "np.save(sys.argv[2], np.column_stack([r.x, r.q, r.p, r.w]))")
    check([python, "-c", code, scenario, tmp_path / "state.npy"])
    check([BINARY, "run", scenario, "--out", tmp_path / "cli", "--no-figures", "-q"])
    data = np.loadtxt(tmp_path / "cli" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    # The same compiler and flags (Release) as the CLI's: the same numbers to the last bit.
    assert np.array_equal(np.load(tmp_path / "state.npy"), data[:, 1:14])
