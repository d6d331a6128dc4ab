"""The bridge node's parameters get the plausibility warnings a bridge spec gets on the command line.

A value the model computes but no real bridge has (:mod:`adm_sim.model.plausibility`) is warned once,
naming the parameter, its value, unit and plausible range, at start-up and when it is set at run
time; the same value set again is not warned again; a plausible preset is not warned at all.
In-process nodes on an isolated context.
"""

import time
import warnings

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")
from rclpy.parameter import Parameter  # noqa: E402

from adm_sim.errors import PlausibilityWarning  # noqa: E402
from adm_sim.nodes.bridge_node import BridgeNode  # noqa: E402
from ros_fixtures import ctx, ros_domain  # noqa: E402,F401  (fixtures)



def _said(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = call()
    return out, [str(w.message) for w in caught if issubclass(w.category, PlausibilityWarning)]


def test_plausible_preset_is_quiet(ctx):
    node, said = _said(lambda: BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value="B3")]))
    try:
        assert said == []
    finally:
        node.destroy_node()


def test_start_up_values_warned_by_parameter(ctx):
    node, said = _said(lambda: BridgeNode(context=ctx, parameter_overrides=[
        Parameter("bridge", value="B3"), Parameter("mu_kg_m", value=150.0)]))
    try:
        mu = [s for s in said if s.startswith("mu_kg_m:")]
        assert mu == ["mu_kg_m: 150 kg/m is outside the plausible range [1995, 46190] kg/m for L = 15 m; "
                      "Table 1 (Eq. 19) spans the real bridges from mu6 = 0.1214 L + 2.1691 t/m (lightest, "
                      "steel/composite) to mu1 = 0.843 L + 10.45 t/m (heaviest, concrete); a factor 2 beyond it "
                      "is no railway bridge"]
        # n0 follows from the preset's EJ and the new mass: sqrt(7739 / 150) x 8.262 Hz = 59.35 Hz
        assert any(s.startswith("n0 (from EJ_Nm2 and mu_kg_m): 59.35 Hz is outside the plausible range "
                                "[2.795, 23.82] Hz for L = 15 m") for s in said), said
    finally:
        node.destroy_node()


def test_run_time_set_warned_once(ctx):
    node = BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value="B3")])
    try:
        res, said = _said(lambda: node.set_parameters([Parameter("zeta_pct", value=0.0185)]))
        assert res[0].successful
        assert said == ["zeta_pct: 0.0185 % is outside the plausible range >= 0.1 % (if 0.0185 is a fraction, "
                        "write zeta_pct=1.85); EN 1991-2 Table 6.6 lower limits are 0.5 .. 4 %, so a value "
                        "below 0.1 % looks like a fraction typed into the % key"]
        assert node.bridge.damping_ratio == pytest.approx(0.0185e-2, rel=1e-12)  # a warning, not a refusal
        _, again = _said(lambda: node.set_parameters([Parameter("zeta_pct", value=0.0185)]))
        assert again == []  # once per node
        _, back = _said(lambda: node.set_parameters([Parameter("zeta_pct", value=1.85)]))
        assert back == []
    finally:
        node.destroy_node()


def test_driver_warns_about_a_run_result_once(ros_domain):
    """A run's result no real deck survives (4174 m/s², 0.07 m on a 4 m span): one warning per
    bound, and one WARN status per warning on /diagnostics, carrying the run id."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rclpy.serialization import deserialize_message

    from adm_sim.nodes.driver import DIAG_PLAUSIBILITY
    from ros_fixtures import driver_node

    with driver_node(ros_domain.domain_id) as d:
        d._desc["bridge"] = {"bridge": {"span_m": 4.0}}
        sent = []
        d.pub_plausibility.publish = sent.append
        r = {"run_id": 7, "model": "dim", "speeds_kmh": np.array([250.0, 300.0]),
             "max_acc_m_s2": np.array([12.0, 4173.5]), "max_disp_m": np.array([0.001, 0.07])}
        texts, said = _said(lambda: d.warn_implausible(r))
        assert said == texts and [t.split(" is outside")[0] for t in texts] == [
            "run 7 (DIM) at 300 km/h: peak acceleration: 4174 m/s²", "run 7 (DIM) at 300 km/h: peak deflection: 0.07 m"]
        assert len(sent) == 1
        st = deserialize_message(sent[0], DiagnosticArray).status  # published as the bytes it records
        assert [s.message for s in st] == texts
        assert {s.level for s in st} == {DiagnosticStatus.WARN} and {s.name for s in st} == {DIAG_PLAUSIBILITY}
        assert [(kv.key, kv.value) for kv in st[0].values] == [("run_id", "7")]
        r.update(max_acc_m_s2=np.array([1.0, 2.6]), max_disp_m=np.array([0.001, 0.003]))
        assert _said(lambda: d.warn_implausible(r)) == ([], [])
        assert len(sent) == 1


def test_driver_records_its_own_status_once_as_published(ros_domain, tmp_path):
    """The driver's own WARN status is in its MCAP as soon as it is published, before the driver's
    own /diagnostics subscription (which records the bridge's statuses) hands it back, and that echo
    is recognised by its bytes and not written again."""
    from adm_sim.nodes.driver import DIAG_PLAUSIBILITY
    from adm_sim.recording.mcap_log import read_messages
    from ros_fixtures import driver_node

    mcap = tmp_path / "own.mcap"
    with driver_node(ros_domain.domain_id, record_path=str(mcap)) as d:
        d._desc["bridge"] = {"bridge": {"span_m": 4.0}}
        r = {"run_id": 3, "model": "mlm", "speeds_kmh": np.array([300.0]), "max_acc_m_s2": np.array([4173.5]),
             "max_disp_m": np.array([0.07])}
        texts, _ = _said(lambda: d.warn_implausible(r))
        assert d.rec.mcap.message_count == 1  # written as published (nothing else is on this domain)
        t_end = time.monotonic() + 10.0
        while d._own and time.monotonic() < t_end:
            time.sleep(0.02)
        assert not d._own  # the echo came back and was matched to it
        d.rec.finish(keep=True)
    st = [s for _t, _ns, m in read_messages(mcap, topics=["/diagnostics"]) for s in m.status]
    assert [(s.name, s.message) for s in st] == [(DIAG_PLAUSIBILITY, t) for t in texts] and len(texts) == 2
