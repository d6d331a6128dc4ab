"""A co-simulated DIM run on a rough track (the train node's ``irregularity`` parameter) equals
the in-process numpy stepper with the same profile, bit for bit (as on a smooth track,
tests/ros/test_ros_cosim.py). Small case: B3 x ICE-2, 3 speeds from 290 km/h (the slowest sets the
step: 1400 steps, 2030 from 200 km/h), 4 steps per period of mode 3, the bridge and train nodes
composed in one process as the launch scripts start them (the same nodes and messages; that the
exchange is the same bit for bit across two processes is tests/ros/test_ros_cosim.py's), the
monitoring topics thinned as there (outputs only: the result is of every step)."""

import numpy as np
import pytest

pytest.importorskip("rclpy")
from ros_fixtures import driver_node, node_procs, ros_domain  # noqa: E402,F401

from adm_sim.inputs.bridges import resolve_bridge  # noqa: E402
from adm_sim.inputs.track_profile import parse_irregularity  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402

pytestmark = pytest.mark.slow  # every test here starts processes

SPEEDS = "290,320,350"
STEP = {"steps_per_period": 4.0, "free_vibration_periods": 1.0}
SPARSE = {"monitor_every_steps": 16, "beam_every_steps": 64}
SPEC = "german-high:seed=4+joint:at=6:length=1:depth=0.002"


def test_cosim_on_rough_track_is_run_sweep_bit_for_bit(node_procs, ros_domain):
    node_procs.start("bridge_train", "adm_sim.nodes.composed",
                     {"bridge:bridge": "B3", **{f"bridge:{k}": v for k, v in {**STEP, **SPARSE}.items()},
                      "train:speeds_kmh": SPEEDS, "train:irregularity": SPEC})
    bridge, train = resolve_bridge("B3"), load_train("ICE-2")
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        r = d.request_run(model="dim", delta_zeta=0.0)
    ref = run_sweep(bridge, train, "dim", r["speeds_kmh"],
                    options=StepOptions(**STEP, irregularity=parse_irregularity(SPEC, bridge.span_m)))
    smooth = run_sweep(bridge, train, "dim", r["speeds_kmh"], options=StepOptions(**STEP))
    np.testing.assert_array_equal(r["speeds_kmh"], [290.0, 320.0, 350.0])
    np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2)
    np.testing.assert_array_equal(r["max_disp_m"], ref.max_disp_m)
    assert np.max(np.abs(ref.max_acc_m_s2 / smooth.max_acc_m_s2 - 1.0)) > 0.01  # the profile acted


def test_bad_irregularity_parameter_refused():
    """A class the standard does not have: the train node refuses it at start-up, one line, exit 2."""
    import subprocess
    import sys

    from adm_sim.processes.dds_env import local_ros_env

    with local_ros_env() as env:
        r = subprocess.run([sys.executable, "-m", "adm_sim.nodes.train_node", "--ros-args", "-p",
                            "irregularity:=fra-0:seed=1"], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    (only,) = r.stderr.splitlines()
    assert only.startswith("error: train: irregularity: spectrum = 'fra-0' is not allowed; allowed german-low")
