"""Bridge and train node parameters: descriptors, rejection reasons, old values kept.

In-process nodes on an isolated ``rclpy.context.Context`` (no other process involved).
"""

import subprocess
import sys

import pytest

rclpy = pytest.importorskip("rclpy")
from rcl_interfaces.msg import ParameterType  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from adm_sim.nodes.bridge_node import BridgeNode  # noqa: E402
from adm_sim.nodes.train_node import TrainNode  # noqa: E402
from ros_fixtures import ctx  # noqa: E402,F401  (fixture)



@pytest.fixture
def bridge(ctx):
    n = BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value="B1")])
    yield n
    n.destroy_node()


@pytest.fixture
def train(ctx):
    n = TrainNode(context=ctx)
    yield n
    n.destroy_node()


def test_descriptors_carry_units_and_ranges(bridge, train):
    d = bridge.describe_parameter("span_m")
    assert d.type == ParameterType.PARAMETER_DOUBLE
    assert "[m]" in d.description
    assert d.additional_constraints == "1 <= span_m <= 150 m"
    z = bridge.describe_parameter("zeta_pct")
    assert "[%]" in z.description and z.additional_constraints == "0 <= zeta_pct <= 20 %"
    assert bridge.describe_parameter("bridge").read_only
    # one range for a span and a deck (a deck takes 50); one simply supported span is held to 20 on set
    assert bridge.describe_parameter("n_modes").additional_constraints == "1 <= n_modes <= 50 -"
    # ranges are checked by the nodes' on-set callback (the core's wording), not by rclpy
    assert not d.floating_point_range and not bridge.describe_parameter("n_modes").integer_range
    assert "km/h" in train.describe_parameter("speeds_kmh").description


def test_preset_gives_defaults(bridge):
    assert bridge.get_parameter("span_m").value == 15.0
    assert bridge.get_parameter("mu_kg_m").value == pytest.approx(19042.0)
    from adm_sim.inputs.bridges import resolve_bridge

    assert bridge.bridge == resolve_bridge("B1")  # exactly the preset: no % round trip


@pytest.mark.parametrize("name, value, words", [
    ("span_m", -5.0, ["span_m", "-5", "m", "[1, 150]"]),
    ("zeta_pct", 25.0, ["zeta_pct", "25", "%", "[0, 20]"]),
    ("zeta_pct", -1.0, ["zeta_pct", "-1", "%", "[0, 20]"]),
    ("n_modes", 0, ["n_modes", "0", "[1, 50]"]),
    ("n_modes", 21, ["n_modes", "21", "[1, 20]"]),  # B1 is one simply supported span
    ("delta_zeta", -0.05, ["delta_zeta", "-0.05", "fraction", "[-0.0185, 0.2]"]),
    ("n0_hz", 0.2, ["n0_hz", "0.2", "Hz", "[0.5, 100]"]),
    ("track_type", "gravel", ["track_type", "gravel", "ballasted", "direct_fastening"]),
    ("delta_zeta_lanes", "0.01,abc", ["delta_zeta_lanes", "abc"]),
])
def test_bridge_rejects_with_reason_and_keeps_old_value(bridge, name, value, words):
    old = bridge.get_parameter(name).value
    old_bridge = bridge.bridge
    (res,) = bridge.set_parameters([Parameter(name, value=value)])
    assert not res.successful
    for w in words:
        assert w in res.reason, res.reason
    assert bridge.get_parameter(name).value == old
    assert bridge.bridge is old_bridge


def test_bridge_accepts_valid_set(bridge):
    (res,) = bridge.set_parameters([Parameter("span_m", value=20.0)])
    assert res.successful
    assert bridge.bridge.span_m == 20.0
    (res,) = bridge.set_parameters([Parameter("n0_hz", value=5.0)])
    assert res.successful and bridge.bridge.n0_hz == pytest.approx(5.0)


def test_read_only_preset(bridge):
    (res,) = bridge.set_parameters([Parameter("bridge", value="B2")])
    assert not res.successful and "read-only" in res.reason


@pytest.mark.parametrize("name, value, words", [
    ("train", "TGV-Z", ["train", "TGV-Z"]),
    ("model", "fem", ["model", "fem", "mlm", "dim"]),
    ("speeds_kmh", "100:50:1", ["speeds_kmh", "100:50:1", "km/h"]),
    ("speeds_kmh", "700", ["speeds_kmh", "700 km/h", "[1, 600] km/h"]),
    ("mlm_block_steps", 0, ["mlm_block_steps", "0", "steps"]),
])
def test_train_rejects_with_reason_and_keeps_old_value(train, name, value, words):
    old = train.get_parameter(name).value
    (res,) = train.set_parameters([Parameter(name, value=value)])
    assert not res.successful
    for w in words:
        assert w in res.reason, res.reason
    assert train.get_parameter(name).value == old


def test_rejection_over_the_parameter_service(ctx, bridge, train):
    """A remote client (as the calibration node) gets the reason through the service."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter_client import AsyncParameterClient

    client = rclpy.create_node("client", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    for n in (bridge, train, client):
        ex.add_node(n)
    try:
        pc = AsyncParameterClient(client, "train")
        assert pc.wait_for_services(timeout_sec=5.0)
        fut = pc.set_parameters([Parameter("train", value="Nonexistent")])
        ex.spin_until_future_complete(fut, timeout_sec=5.0)
        (r,) = fut.result().results
        assert not r.successful and "Nonexistent" in r.reason
        assert train.get_parameter("train").value == "ICE-2"
        pb = AsyncParameterClient(client, "bridge")
        fut = pb.set_parameters([Parameter("span_m", value=-1.0)])
        ex.spin_until_future_complete(fut, timeout_sec=5.0)
        (r,) = fut.result().results
        assert not r.successful and "span_m: -1 m is out of range" in r.reason
    finally:
        ex.shutdown()
        client.destroy_node()


def test_bad_preset_fails_at_start(ctx):
    from adm_sim.errors import InputError

    with pytest.raises(InputError, match="B9"):
        BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value="B9")])


@pytest.mark.slow
def test_launchers_check_parameters_without_rclpy():
    """The parameter specs and their mapping to a bridge and a train are ROS-free: the launchers'
    checks import no node module and no rclpy."""
    from pathlib import Path

    code = ("import sys; sys.path.insert(0, 'launch_scripts'); import _supervisor as s; s.launch_param_specs(); "
            "s.check_inputs(bridge='B1', train='ICE-2', speeds='200:300:5', params_file='ros_ws/params/b1_ice2.yaml'); "
            "bad = [m for m in sys.modules if m == 'rclpy' or m.startswith(('adm_sim.nodes.', 'adm_calib.nodes.')) "
            "and not m.endswith('.params')]; "
            "print(bad)")
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
