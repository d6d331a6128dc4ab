"""The bridge node checks the DIM's contact assumption (tests/integrate/test_contact.py) in a co-simulated
run: the contact forces it forms from the train node's interaction forces and the wheel inertia it
carries give the same first loss and smallest forces as the numpy stepper, bit for bit, in its
``done`` record, the driver's result and ``/diagnostics``. Small case as tests/ros/test_irregularity_ros.py:
B3 x ICE-2, 4 steps per period of mode 3, a 2 mm dip that lifts the wheel at 320 km/h, not at 120."""

import pytest

pytest.importorskip("rclpy")
from ros_fixtures import driver_node, node_procs, ros_domain  # noqa: E402,F401

from adm_sim.integrate.contact import CONTACT_LOST  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep  # noqa: E402
from adm_sim.inputs.bridges import resolve_bridge  # noqa: E402
from adm_sim.inputs.track_profile import parse_irregularity  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402

STEP = {"steps_per_period": 4.0, "free_vibration_periods": 1.0}
SPARSE = {"monitor_every_steps": 16, "beam_every_steps": 64}
SPEC = "joint:at=6:length=1:depth=0.002"


@pytest.mark.slow
def test_cosim_reports_the_contact_loss_of_run_sweep(node_procs, ros_domain, tmp_path):
    node_procs.start("bridge_train", "adm_sim.nodes.composed",
                     {"bridge:bridge": "B3", **{f"bridge:{k}": v for k, v in {**STEP, **SPARSE}.items()},
                      "train:speeds_kmh": "120,320", "train:irregularity": SPEC})
    bridge, train = resolve_bridge("B3"), load_train("ICE-2")
    with driver_node(ros_domain.domain_id, record_path=str(tmp_path / "run.mcap")) as d:
        d.wait_for_graph()
        with pytest.warns(UserWarning, match=r"contact lost: the wheel of axle 1 would lift off the rail at 320 km/h"):
            r = d.request_run(model="dim", delta_zeta=0.0)
        done = d._bridge_status(r["run_id"])
    ref = run_sweep(bridge, train, "dim", r["speeds_kmh"],
                    options=StepOptions(**STEP, irregularity=parse_irregularity(SPEC, bridge.span_m))).contact
    got = r["contact"]
    assert ref.status == got["status"] == CONTACT_LOST
    assert got["first_loss"] == ref.first()
    assert got["min_contact_force_n"] == [float(x) for x in ref.min_n]
    assert done["state"] == "done" and done["contact"] == got
    # /diagnostics as recorded: the bridge's final status names the loss, WARN at least
    from adm_sim.recording.mcap_log import read_messages

    finals = [st for _t, _ns, arr in read_messages(tmp_path / "run.mcap", topics=["/diagnostics"]) for st in arr.status
              if {kv.key: kv.value for kv in st.values}.get("final") == "True"
              and {kv.key: kv.value for kv in st.values}.get("model") == "dim"]
    assert finals
    st = finals[-1]
    assert {kv.key: kv.value for kv in st.values}["contact"] == CONTACT_LOST
    assert (st.level[0] if isinstance(st.level, bytes) else st.level) >= 1 and "contact lost: the wheel of axle 1 would lift off the rail at 320 km/h" in st.message
