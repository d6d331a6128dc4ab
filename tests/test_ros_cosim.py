"""A co-simulated run (bridge and train nodes in separate processes) reproduces the core.

The exchange carries float64 exactly and both nodes call the core's BridgeSide/TrainSide methods
in the order of :func:`adm_sim.sweep.run_sweep`, so the peaks agree to 1e-9 relative (in practice
bitwise). Small case for speed: B3 x ICE-2, 5 speeds, 4 steps per period of mode 3, one
fundamental period of free vibration.
"""

import numpy as np
import pytest

pytest.importorskip("rclpy")
from ros_fixtures import driver_node, node_procs, ros_domain  # noqa: E402,F401

from adm_sim.bridge import resolve_bridge  # noqa: E402
from adm_sim.stepping import StepOptions  # noqa: E402
from adm_sim.sweep import run_sweep  # noqa: E402
from adm_sim.trains import load_train  # noqa: E402

SPEEDS = "200,250,290,330,350"
STEP = {"steps_per_period": 4.0, "free_vibration_periods": 1.0}


def test_cosim_reproduces_run_sweep(node_procs, ros_domain):
    node_procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": "B3", **STEP})
    node_procs.start("train", "adm_sim.nodes.train_node", {"speeds_kmh": SPEEDS})
    bridge, train = resolve_bridge("B3"), load_train("ICE-2")
    opts = StepOptions(**STEP)
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        for model, dz in (("mlm", 0.0), ("dim", 0.0), ("mlm", 0.004)):
            r = d.request_run(model=model, delta_zeta=dz)
            ref = run_sweep(bridge, train, model, r["speeds_kmh"], delta_zeta=dz, options=opts)
            np.testing.assert_array_equal(r["speeds_kmh"], [200, 250, 290, 330, 350])
            rel = np.max(np.abs(r["max_acc_m_s2"] / ref.max_acc_m_s2 - 1.0))
            assert rel <= 1e-9, (model, rel)
            np.testing.assert_allclose(r["max_disp_m"], ref.max_disp_m, rtol=1e-9, atol=0)
            np.testing.assert_array_equal(r["delta_zeta"], dz)
        # per-lane damping (the calibration's vectorised ladder) = one run_sweep with a dz array
        lanes = np.array([0.0, 0.001, 0.002, 0.004, 0.01])
        r = d.request_run(model="mlm", delta_zeta_lanes=lanes)
        ref = run_sweep(bridge, train, "mlm", r["speeds_kmh"], delta_zeta=lanes, options=opts)
        assert np.max(np.abs(r["max_acc_m_s2"] / ref.max_acc_m_s2 - 1.0)) <= 1e-9
        d.request_run(delta_zeta_lanes=[])


def test_wrong_lane_count_is_reported(node_procs, ros_domain):
    """A bad run request fails with the bridge's reason and both nodes stay up."""
    from adm_sim.nodes.driver import RunError

    node_procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": "B3", **STEP})
    node_procs.start("train", "adm_sim.nodes.train_node", {"speeds_kmh": "250,300", "model": "mlm"})
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        with pytest.raises(RunError, match="delta_zeta_lanes: 3 values for 2 speed lanes"):
            d.request_run(delta_zeta_lanes=[0.0, 0.01, 0.02])
        r = d.request_run(delta_zeta_lanes=[])
        assert r["max_acc_m_s2"].shape == (2,)
    assert all(p.poll() is None for p in node_procs.procs.values())
