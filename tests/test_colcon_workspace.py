"""ros_ws is a real ROS 2 workspace built with colcon, as a ROS user builds one, in two layers:

- bench_msgs (ament_cmake, against the wheels' CMake exports) is built by colcon in ``make setup``
  (scripts/setup_env.sh) with the venv as its merged install space, so every fresh machine proves that build
  before any test runs; the test checks colcon's record of it in the venv.
- Here, every ament_python package is built by colcon from a copy of ros_ws/src into an install space outside
  the repository, on top of that underlay, and the installed commands run from it the colcon way
  (`. install/setup.sh`, then install/PKG/lib/PKG/COMMAND, which is what `ros2 run PKG COMMAND` runs).

The venv is the underlay, as /opt/ros/jazzy is in a regular installation: AMENT_PREFIX_PATH and
CMAKE_PREFIX_PATH name it while building. The venv also holds the bench's packages installed editable (make
setup), so a module or an entry point could come from either. install/setup.sh puts the install space first on
PYTHONPATH, which Python searches before the venv's site-packages and the paths its .pth files add, and
importlib.metadata, like bench_engine.plugins, takes the first distribution of a name on sys.path: the installed
commands see only the install space's copies. The test asserts that for every package and for the registered
scenarios, rather than building a second venv.
"""

from __future__ import annotations

import ast
import configparser
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "ros_ws" / "src"
VENV = Path(sys.prefix)
COLCON = Path(sys.executable).parent / "colcon"
PYTHON_PACKAGES = sorted(p.parent.name for p in SRC.glob("*/setup.py"))
PACKAGES = sorted(p.parent.name for p in SRC.glob("*/package.xml"))
UNDERLAY_PACKAGES = ["bench_msgs"]
"""Built by colcon into the venv by make setup (scripts/setup_env.sh)."""


def console_scripts(package: str) -> list[str]:
    """The console_scripts names a package's setup.py declares."""
    for node in ast.walk(ast.parse((SRC / package / "setup.py").read_text())):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if isinstance(key, ast.Constant) and key.value == "console_scripts":
                    return [elt.value.split("=")[0].strip() for elt in value.elts]
    return []


def user_env(**extra: str) -> dict[str, str]:
    """A fresh shell's environment, with the venv activated and DDS kept on this host."""
    keep = {k: os.environ[k] for k in ("HOME", "TMPDIR", "LANG", "OPENBLAS_NUM_THREADS") if k in os.environ}
    return {
        **keep,
        "PATH": f"{VENV / 'bin'}:/usr/bin:/bin",
        "VIRTUAL_ENV": str(VENV),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        **extra,
    }


def sourced(install: Path, *command: str, timeout: float = 60) -> subprocess.CompletedProcess:
    """Run a command after `. install/setup.sh` on top of the venv underlay (AMENT_PREFIX_PATH, as a sourced
    /opt/ros/jazzy/setup.sh would set it)."""
    return subprocess.run(
        ["sh", "-c", '. "$0/setup.sh" && exec "$@"', str(install), *command],
        env=user_env(AMENT_PREFIX_PATH=str(VENV)),
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.fixture(scope="module")
def install(tmp_path_factory) -> Path:
    """colcon build of a copy of ros_ws/src without the underlay's packages (build, install and log bases in a
    scratch directory)."""
    assert COLCON.is_file(), f"{COLCON} is missing: run make setup (requirements.txt names colcon-core, colcon-ros)"
    work = tmp_path_factory.mktemp("colcon")
    shutil.copytree(SRC, work / "src", ignore=shutil.ignore_patterns("*.egg-info", "__pycache__", *UNDERLAY_PACKAGES))
    env = user_env(AMENT_PREFIX_PATH=str(VENV), CMAKE_PREFIX_PATH=str(VENV), COLCON_HOME=str(work / "colcon_home"))
    res = subprocess.run(
        [
            str(COLCON),
            "--log-base",
            str(work / "log"),
            "build",
            "--base-paths",
            str(work / "src"),
            "--build-base",
            str(work / "build"),
            "--install-base",
            str(work / "install"),
            "--cmake-args",
            f"-DPython3_EXECUTABLE={sys.executable}",
            "-DBUILD_TESTING=OFF",
        ],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return work / "install"


@pytest.mark.parametrize("package", PYTHON_PACKAGES)
def test_setup_cfg_puts_the_console_scripts_where_ros2_run_looks(package):
    cfg = configparser.ConfigParser()
    cfg.read(SRC / package / "setup.cfg")
    assert cfg["develop"]["script_dir"] == cfg["install"]["install_scripts"] == f"$base/lib/{package}"


def test_make_setup_built_the_interface_package_with_colcon_into_the_venv():
    for package in UNDERLAY_PACKAGES:
        assert (VENV / "share" / "colcon-core" / "packages" / package).is_file(), f"run make setup: {package}"
        assert (VENV / "share" / package / "package.xml").is_file()
        assert (VENV / "share" / "ament_index" / "resource_index" / "rosidl_interfaces" / package).is_file()
    assert sorted(PYTHON_PACKAGES + UNDERLAY_PACKAGES) == PACKAGES


def test_colcon_builds_every_package_with_its_console_scripts(install):
    assert sorted(p.name for p in install.iterdir() if p.is_dir()) == PYTHON_PACKAGES
    missing = [
        f"{p}/lib/{p}/{name}"
        for p in PYTHON_PACKAGES
        for name in console_scripts(p)
        if not (install / p / "lib" / p / name).is_file()
    ]
    assert not missing, missing
    assert {"bench_launch", "bench_score", "bench_montecarlo", "bench_replay", "bench_sweep", "bench_demo"} <= set(
        console_scripts("bench_eval")
    )
    assert "bench_recover_bag" in console_scripts("bench_engine")


def test_the_install_space_shadows_the_venvs_editable_packages(install):
    code = (
        "import importlib, importlib.metadata as md\n"
        "from bench_engine import plugins\n"
        f"for name in {PYTHON_PACKAGES!r}:\n"
        "    print(importlib.import_module(name).__file__)\n"
        f"for name in {PYTHON_PACKAGES!r}:\n"
        "    print(md.distribution(name).locate_file(''))\n"
        "print(plugins.load('scenarios', 'leo_radar'))\n"
    )
    res = sourced(install, "python", "-c", code)
    assert res.returncode == 0, res.stderr[-2000:]
    outside = [line for line in res.stdout.split() if not Path(line).resolve().is_relative_to(install.resolve())]
    assert len(res.stdout.split()) == 2 * len(PYTHON_PACKAGES) + 1 and not outside, outside


def test_every_installed_command_answers_help(install):
    commands = [
        f"{p}/lib/{p}/{name}" for p in PYTHON_PACKAGES for name in console_scripts(p) if name.startswith("bench_")
    ]
    loop = 'for c in "$@"; do "$0/$c" --help > /dev/null || { echo "failed: $c" >&2; exit 1; }; done'
    res = sourced(install, "sh", "-c", loop, str(install), *commands, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]


def test_the_installed_launcher_runs_a_short_graph(install, tmp_path):
    launch = install / "bench_eval" / "lib" / "bench_eval" / "bench_launch"
    res = sourced(
        install,
        str(launch),
        "leo_radar",
        "--set",
        "time.duration=5",
        "--single-process",
        "--no-score",
        "--out",
        str(tmp_path / "run"),
        timeout=120,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    assert (tmp_path / "run" / "bag" / "metadata.yaml").is_file() and list((tmp_path / "run" / "bag").glob("*.mcap"))
