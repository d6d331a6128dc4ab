"""ros_ws/ is a colcon workspace: both packages build with colcon from PyPI, and the nodes run
from the install space as a ROS 2 user runs them (``source install/setup.sh``, the executables
in ``lib/<package>``, the params files from ``share/adm_sim/params``).
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

from adm_sim.bridge import resolve_bridge  # noqa: E402
from adm_sim.step_grid import StepOptions  # noqa: E402
from adm_sim.sweep import parse_speeds, run_sweep  # noqa: E402
from adm_sim.trains import load_train  # noqa: E402

COLCON = Path(sys.executable).parent / "colcon"


@pytest.fixture(scope="module")
def install(tmp_path_factory):
    """``colcon build`` of ros_ws into a temporary build, install and log space."""
    base = tmp_path_factory.mktemp("colcon")
    cmd = [str(COLCON), "--log-base", str(base / "log"), "build", "--base-paths", str(ROOT / "ros_ws"),
           "--build-base", str(base / "build"), "--install-base", str(base / "install")]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=base)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return base / "install"


def in_install(install, command):
    """``sh -c '. install/setup.sh && <command>'``: the environment a sourced workspace gives."""
    return ["sh", "-c", f'. "{install}/setup.sh" && {command}']


def test_install_space_layout(install):
    for pkg, exe in (("adm_sim", "bridge_node"), ("adm_sim", "train_node"), ("adm_sim", "driver"),
                     ("adm_calib", "calibration_node")):
        path = install / pkg / "lib" / pkg / exe
        assert path.is_file() and path.stat().st_mode & 0o111, path
        assert (install / pkg / "share" / "ament_index" / "resource_index" / "packages" / pkg).is_file()
        assert (install / pkg / "share" / pkg / "package.xml").is_file()
    share = install / "adm_sim" / "share" / "adm_sim"
    for src in sorted((ROOT / "ros_ws" / "params").glob("*.yaml")) + [ROOT / "ros_ws" / "dds" / "fastdds_shm_only.xml"]:
        installed = share / src.parent.name / src.name
        assert installed.read_bytes() == src.read_bytes(), installed


def test_sourced_workspace_imports_the_installed_packages(install, ros_domain):
    out = subprocess.run(in_install(install, f'"{sys.executable}" -c "import adm_sim, adm_calib; '
                                             f'print(adm_sim.__file__); print(adm_calib.__file__)"'),
                         capture_output=True, text=True, timeout=60, env=dict(ros_domain), cwd="/")
    assert out.returncode == 0, out.stderr
    files = out.stdout.split()
    assert files == [str(install / p / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}"
                         / "site-packages" / p / "__init__.py") for p in ("adm_sim", "adm_calib")]


def test_node_from_install_space_rejects_bad_parameter(install, ros_domain):
    exe = install / "adm_sim" / "lib" / "adm_sim" / "bridge_node"
    out = subprocess.run(in_install(install, f'"{exe}" --ros-args -p span_m:=-5.0'), capture_output=True,
                         text=True, timeout=60, env=dict(ros_domain), cwd="/")
    assert out.returncode == 2
    assert out.stderr.splitlines() == ["error: bridge: span_m: -5 m is out of range; allowed [1, 150] m"]


def test_nodes_from_install_space_run_the_installed_params(install, ros_domain, tmp_path):
    """bridge_node and train_node started from the install space with the installed
    sweep_b1_mlm.yaml co-simulate the MLM sweep of the core, bit for bit."""
    params = install / "adm_sim" / "share" / "adm_sim" / "params" / "sweep_b1_mlm.yaml"
    procs = NodeProcs(ros_domain, tmp_path)
    try:
        for exe in ("bridge_node", "train_node"):
            path = install / "adm_sim" / "lib" / "adm_sim" / exe
            procs.start_command(exe, in_install(install, f'exec "{path}" --ros-args --params-file "{params}"'))
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


def test_colcon_is_pinned():
    req = (ROOT / "requirements.txt").read_text().splitlines()
    for name in ("colcon-core", "colcon-ros", "colcon-python-setup-py"):
        assert any(line.startswith(f"{name}==") for line in req), name
    assert shutil.which("colcon", path=str(COLCON.parent)) is not None
