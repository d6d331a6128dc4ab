"""ros_ws/ is a colcon workspace: both packages build with colcon from PyPI, and the nodes run
from the install space as a ROS 2 user runs them (``source install/setup.sh``, the executables
in ``lib/<package>``, the params files from ``share/adm_sim/params``). The manifests are valid
(catkin_pkg), colcon identifies both packages as ``ros.ament_python`` and builds ``adm_sim``
first, the ament index finds them after sourcing, and ``colcon test`` runs their own tests.
"""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("colcon_ros")
from ros_fixtures import ROOT, NodeProcs, driver_node, ros_domain  # noqa: E402,F401

from adm_sim.inputs.bridges import resolve_bridge  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.inputs.speeds import parse_speeds  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402

COLCON = Path(sys.executable).parent / "colcon"


PACKAGES = ("adm_sim", "adm_calib")


def test_manifests_are_valid_format3():
    """Both package.xml parse and validate with catkin_pkg (a maintainer e-mail it accepts, the
    ament_python build type), and adm_calib depends on adm_sim for build and run."""
    from catkin_pkg.package import parse_package

    pkgs = {}
    for name in PACKAGES:
        pkg = parse_package(str(ROOT / "ros_ws" / name / "package.xml"))
        pkg.validate()  # raises InvalidPackage (e.g. on an e-mail without a domain)
        assert pkg.name == name and pkg.package_format == 3
        assert pkg.get_build_type() == "ament_python"
        assert [t.name for t in pkg.test_depends] == ["python3-pytest"]
        pkgs[name] = pkg
    assert "adm_sim" in [d.name for d in pkgs["adm_calib"].build_depends]
    assert "adm_sim" in [d.name for d in pkgs["adm_calib"].exec_depends]


def test_gitignore_holds_the_colcon_spaces():
    lines = (ROOT / ".gitignore").read_text().splitlines()
    for space in ("build/", "install/", "log/"):
        assert space in lines, space


@pytest.fixture(scope="module")
def colcon_base(tmp_path_factory):
    """``colcon build`` of ros_ws into a temporary build, install and log space; adm_sim finishes
    before adm_calib starts (its declared dependency)."""
    base = tmp_path_factory.mktemp("colcon")
    cmd = [str(COLCON), "--log-base", str(base / "log"), "build", "--base-paths", str(ROOT / "ros_ws"),
           "--build-base", str(base / "build"), "--install-base", str(base / "install")]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=base)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    events = [line for line in out.stdout.splitlines() if line.startswith(("Starting >>>", "Finished <<<"))]
    assert events.index("Starting >>> adm_calib") > next(
        i for i, e in enumerate(events) if e.startswith("Finished <<< adm_sim")), events
    return base


@pytest.fixture(scope="module")
def install(colcon_base):
    return colcon_base / "install"


def in_install(install, command):
    """``sh -c '. install/setup.sh && <command>'``: the environment a sourced workspace gives."""
    return ["sh", "-c", f'. "{install}/setup.sh" && {command}']


@pytest.mark.slow
def test_install_space_layout(install):
    for pkg, exe in (("adm_sim", "bridge_node"), ("adm_sim", "train_node"), ("adm_sim", "driver"),
                     ("adm_calib", "calibration_node")):
        path = install / pkg / "lib" / pkg / exe
        assert path.is_file() and path.stat().st_mode & 0o111, path
        assert (install / pkg / "share" / "ament_index" / "resource_index" / "packages" / pkg).is_file()
        assert (install / pkg / "share" / pkg / "package.xml").is_file()
    share = install / "adm_sim" / "share" / "adm_sim"
    for src in sorted((ROOT / "ros_ws" / "params").glob("*.yaml")) + [ROOT / "ros_ws" / "dds" / "fastdds_local.xml"]:
        installed = share / src.parent.name / src.name
        assert installed.read_bytes() == src.read_bytes(), installed


@pytest.mark.slow
def test_ament_index_finds_the_packages_after_sourcing(install, ros_domain):
    code = ("from ament_index_python.packages import get_package_share_directory as share; "
            "import pathlib; d = pathlib.Path(share('adm_sim')); print(d); print(share('adm_calib')); "
            "print(sorted(p.name for p in (d / 'params').glob('*.yaml')))")
    out = subprocess.run(in_install(install, f'"{sys.executable}" -c "{code}"'), capture_output=True, text=True,
                         timeout=60, env=dict(ros_domain), cwd="/")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[:2] == [str(install / "adm_sim" / "share" / "adm_sim"), str(install / "adm_calib" / "share" / "adm_calib")]
    assert lines[2] == str(sorted(p.name for p in (ROOT / "ros_ws" / "params").glob("*.yaml")))


@pytest.mark.slow
def test_colcon_test_runs_each_packages_own_tests(colcon_base, ros_domain):
    """``colcon test`` runs the smoke tests in ros_ws/<package>/test against the install space:
    2 per package, all passing (``colcon test-result``)."""
    base = colcon_base
    common = ["--base-paths", str(ROOT / "ros_ws"), "--build-base", str(base / "build"),
              "--install-base", str(base / "install")]
    out = subprocess.run([str(COLCON), "--log-base", str(base / "log"), "test", *common], capture_output=True,
                         text=True, timeout=600, cwd=base, env=dict(ros_domain))
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    res = subprocess.run([str(COLCON), "--log-base", str(base / "log"), "test-result", "--test-result-base",
                          str(base / "build"), "--all"], capture_output=True, text=True, timeout=120, cwd=base)
    assert res.returncode == 0, res.stdout + res.stderr
    for pkg in PACKAGES:
        assert f"build/{pkg}/pytest.xml: 2 tests, 0 errors, 0 failures, 0 skipped" in res.stdout, res.stdout
    assert "Summary: 4 tests, 0 errors, 0 failures, 0 skipped" in res.stdout


@pytest.mark.slow
def test_sourced_workspace_imports_the_installed_packages(install, ros_domain):
    out = subprocess.run(in_install(install, f'"{sys.executable}" -c "import adm_sim, adm_calib; '
                                             f'print(adm_sim.__file__); print(adm_calib.__file__)"'),
                         capture_output=True, text=True, timeout=60, env=dict(ros_domain), cwd="/")
    assert out.returncode == 0, out.stderr
    files = out.stdout.split()
    assert files == [str(install / p / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}"
                         / "site-packages" / p / "__init__.py") for p in ("adm_sim", "adm_calib")]


@pytest.mark.slow
def test_node_from_install_space_rejects_bad_parameter(install, ros_domain):
    exe = install / "adm_sim" / "lib" / "adm_sim" / "bridge_node"
    out = subprocess.run(in_install(install, f'"{exe}" --ros-args -p span_m:=-5.0'), capture_output=True,
                         text=True, timeout=60, env=dict(ros_domain), cwd="/")
    assert out.returncode == 2
    assert out.stderr.splitlines() == ["error: bridge: span_m: -5 m is out of range; allowed [1, 150] m"]


@pytest.mark.slow
def test_nodes_from_install_space_run_the_installed_params(install, ros_domain, tmp_path):
    """bridge_node and train_node started from the install space with the installed
    sweep_b1_mlm.yaml co-simulate the MLM sweep of the core, bit for bit. The bridge publishes its
    monitoring every 16th step and the beam and clock every 64th (``-p`` after the file; outputs
    only, the result is of every step): the in-process driver receives and deserialises what is
    published, about 1.5 s of CPU for the automatic decimation's every 3rd step of the run."""
    params = install / "adm_sim" / "share" / "adm_sim" / "params" / "sweep_b1_mlm.yaml"
    sparse = {"bridge_node": " -p monitor_every_steps:=16 -p beam_every_steps:=64", "train_node": ""}
    procs = NodeProcs(ros_domain, tmp_path)
    try:
        for exe in ("bridge_node", "train_node"):
            path = install / "adm_sim" / "lib" / "adm_sim" / exe
            procs.start_command(exe, in_install(install, f'exec "{path}" --ros-args --params-file "{params}"'
                                                         f'{sparse[exe]}'))
        with driver_node(ros_domain.domain_id) as d:
            d.wait_for_graph()
            r = d.request_run()
        assert all(p.poll() is None for p in procs.procs.values())
    finally:
        procs.stop()
    speeds = parse_speeds("160:350:1")
    ref = run_sweep(resolve_bridge("B1"), load_train("ICE-2"), "mlm", speeds, options=StepOptions())
    np.testing.assert_array_equal(r["speeds_kmh"], speeds)
    np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2)
    assert r["model"] == "mlm"


@pytest.mark.slow
def test_colcon_is_pinned():
    req = (ROOT / "requirements.txt").read_text().splitlines()
    for name in ("colcon-core", "colcon-ros", "colcon-python-setup-py", "colcon-bash", "colcon-package-information"):
        assert any(line.startswith(f"{name}==") for line in req), name
    assert shutil.which("colcon", path=str(COLCON.parent)) is not None


@pytest.mark.slow
def test_colcon_list_and_graph_show_the_packages_in_order():
    """``colcon list`` and ``colcon graph`` (colcon-package-information) on the PyPI path: colcon
    identifies both packages as ``ros.ament_python`` and orders them by their dependency (the graph's
    topological order puts ``adm_sim`` first, against the names' order that ``colcon list`` keeps)."""
    out = subprocess.run([str(COLCON), "list", "--base-paths", str(ROOT / "ros_ws")], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert [line.split("\t") for line in out.stdout.splitlines()] == [
        ["adm_calib", str(ROOT / "ros_ws" / "adm_calib"), "(ros.ament_python)"],
        ["adm_sim", str(ROOT / "ros_ws" / "adm_sim"), "(ros.ament_python)"]]
    out = subprocess.run([str(COLCON), "graph", "--base-paths", str(ROOT / "ros_ws")], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert [line.split()[0] for line in out.stdout.splitlines()] == ["adm_sim", "adm_calib"]  # dependency order


@pytest.mark.slow
def test_install_space_has_setup_bash(install):
    """colcon-bash writes ``install/setup.bash``; sourced in bash it puts the packages on the ament index."""
    assert (install / "setup.bash").is_file() and (install / "adm_sim" / "share" / "adm_sim" / "package.bash").is_file()
    out = subprocess.run(["bash", "-c", f'. "{install}/setup.bash" && echo "$AMENT_PREFIX_PATH"'],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert str(install / "adm_sim") in out.stdout.strip().split(":"), out.stdout
