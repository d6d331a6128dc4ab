"""Continuous decks in the ROS graph: the bridge node's deck parameters, its description record and
beam grid, lockstep runs on a two-span deck against the in-process core, the launchers.

The deck is two spans of B1 (15 + 15 m, EJ 2.667e10 N m^2, mu 19042 kg/m, zeta 1.85 %, 3 modes: the
rule's count, modes at 8.26, 12.9 and 33.0 Hz); the runs take the coarse steps of the co-simulation
tests (4 steps per period of mode 3, one fundamental period of free vibration: 747 steps from
250 km/h) and two speeds. The co-simulation is the numpy stepper split in two processes over float64
exchanges, so a run equals :func:`adm_sim.integrate.sweep.run_sweep` bit for bit, as on one span
(tests/ros/test_ros_cosim.py), and the compiled kernels to 1e-10 relative.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
from rclpy.parameter import Parameter  # noqa: E402

from ros_fixtures import ctx, driver_node, node_procs, ros_domain  # noqa: E402,F401  (fixtures)

from adm_sim import protocol as P  # noqa: E402
from adm_sim.errors import InputError  # noqa: E402
from adm_sim.inputs.bridges import resolve_bridge  # noqa: E402
from adm_sim.inputs.train_files import load_train  # noqa: E402
from adm_sim.integrate.step_grid import StepOptions  # noqa: E402
from adm_sim.integrate.sweep import run_sweep, run_sweep_compiled  # noqa: E402
from adm_sim.model.bridge import Bridge, named_bridge  # noqa: E402
from adm_sim.nodes.bridge_outputs import beam_grid_m  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
B1 = named_bridge("B1")
#: The deck as a spec (the launchers' --bridge) and as the bridge node's parameters on preset B1.
DECK_SPEC = "spans=15/15,EJ=2.667e10,mu=19042,zeta_pct=1.85,name=deck2"
STEP = {"steps_per_period": 4.0, "free_vibration_periods": 1.0}
SPARSE = {"monitor_every_steps": 16, "beam_every_steps": 64}
SPEEDS_KMH = [250.0, 300.0]


def b1_deck(n_modes=3):
    """Two spans of B1's EJ, mu and damping (what ``spans_m = 15,15`` on preset B1 gives)."""
    return Bridge.continuous((15.0, 15.0), B1.EJ_Nm2, B1.mass_per_length_kg_m, B1.damping_ratio, n_modes=n_modes,
                             name="B1", bridge_type="cfb")


# ---------------------------------------------------------------- the beam grid
def test_beam_grid_of_one_span_is_the_equal_steps_of_today():
    np.testing.assert_array_equal(beam_grid_m(B1, 21), np.linspace(0.0, 15.0, 21))


@pytest.mark.parametrize("spans, n_points", [((15.0, 15.0), 21), ((12.0, 16.0, 12.0), 21), ((12.0, 16.0, 12.0), 2),
                                             ((20.0, 25.0, 20.0, 7.5), 40)])
def test_beam_grid_of_a_deck_passes_through_every_support(spans, n_points):
    """Every support is a grid point exactly; each span's points are equally spaced; the grid has
    ``n_points`` points (at least the supports); the deflection there is zero (the shapes at the
    piers below 1e-12 of their maximum)."""
    deck = Bridge.continuous(spans, 2.0e10, 15000.0, 0.015, n_modes=4)
    x = beam_grid_m(deck, n_points)
    sup = deck.supports_m
    assert x.size == max(n_points, len(spans) + 1)
    assert np.all(np.diff(x) > 0.0) and x[0] == 0.0 and x[-1] == sup[-1]
    assert set(sup.tolist()) <= set(x.tolist())
    for i in range(len(spans)):
        inside = x[(x >= sup[i]) & (x <= sup[i + 1])]
        np.testing.assert_allclose(np.diff(inside), spans[i] / (inside.size - 1), rtol=1e-12)
    phi = deck.shapes(x)[0]
    at_supports = np.isin(x, sup)
    assert np.abs(phi[at_supports]).max() < 1e-12


# ---------------------------------------------------------------- parameters (in-process node)
@pytest.fixture
def bridge_b1(ctx):
    from adm_sim.nodes.bridge_node import BridgeNode

    n = BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value="B1")])
    yield n
    n.destroy_node()


@pytest.fixture
def bridge_deck(ctx):
    from adm_sim.nodes.bridge_node import BridgeNode

    n = BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value=DECK_SPEC)])
    yield n
    n.destroy_node()


def test_deck_preset_gives_the_per_span_defaults(bridge_deck):
    """A deck given as the preset (``-p bridge:=spans=15/15,...``, a launcher's --bridge) is exactly the
    reader's deck; its spans, EJ and mu are the defaults of the per-span parameters (repr: exact)."""
    deck = resolve_bridge(DECK_SPEC, continuous=True)
    assert bridge_deck.bridge == deck and bridge_deck.bridge.is_continuous
    assert bridge_deck.get_parameter("spans_m").value == "15.0,15.0"
    assert bridge_deck.get_parameter("span_EJ_Nm2").value == "26670000000.0,26670000000.0"
    assert bridge_deck.get_parameter("span_mu_kg_m").value == "19042.0,19042.0"
    # span_m (one span, spans_m empty) defaults to the longest span: a deck may be longer than one span can be
    assert bridge_deck.get_parameter("span_m").value == 15.0 and bridge_deck.get_parameter("n_modes").value == 3


def test_deck_preset_from_a_bridge_file(ctx, tmp_path):
    """A TOML deck file as the preset (``--bridge deck.toml``): the file's deck, its per-span values
    the parameters' defaults."""
    from adm_sim.inputs.bridges import load_bridge_file
    from adm_sim.nodes.bridge_node import BridgeNode

    f = tmp_path / "deck.toml"
    f.write_text("spans = [12.0, 16.0, 12.0]\nEJ = 2.0e10\nmu = [15000.0, 18000.0, 15000.0]\nzeta_pct = 1.5\n")
    node = BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value=str(f))])
    try:
        assert node.bridge == load_bridge_file(f) and node.bridge.spans_m == (12.0, 16.0, 12.0)
        assert node.get_parameter("span_mu_kg_m").value == "15000.0,18000.0,15000.0"
        assert node.get_parameter("span_m").value == 16.0
    finally:
        node.destroy_node()


def test_deck_parameters_on_a_span_preset_and_the_description(bridge_b1):
    """``spans_m = 15,15`` on preset B1: B1's EJ, mu and damping on two spans; the description record
    carries the spans, the supports, the frequencies and the modal masses (the deck's own numbers),
    and rebuilds the deck (:func:`adm_sim.protocol.bridge_fields`); ``spans_m`` emptied again: B1."""
    sent = []
    bridge_b1.pub_desc.publish = lambda msg: sent.append(json.loads(msg.data))
    (res,) = bridge_b1.set_parameters([Parameter("spans_m", value="15,15")])
    assert res.successful, res.reason
    deck = b1_deck()
    assert bridge_b1.bridge == deck
    rec = sent[-1]
    assert rec["bridge"]["spans_m"] == [15.0, 15.0] and rec["supports_m"] == [0.0, 15.0, 30.0]
    assert rec["frequencies_hz"] == deck.frequencies_hz.tolist()
    assert rec["modal_masses_kg"] == deck.modal_mass_kg.tolist()
    # closed forms of two equal spans: mode 1 is each span's sine (n0 of B1, modal mass mu L_deck / 2),
    # mode 2 each span clamped-pinned (beta L = 3.9266..., the root of tan x = tanh x), mode 3 each span's
    # second sine (4 n0, modal mass mu L_deck / 2 again); to the bisection's and the quadrature's round-off
    n0 = B1.n0_hz
    assert rec["frequencies_hz"] == pytest.approx([n0, (3.926602312047919 / np.pi) ** 2 * n0, 4.0 * n0], rel=1e-12)
    assert rec["modal_masses_kg"][0] == pytest.approx(0.5 * B1.mass_per_length_kg_m * 30.0, rel=1e-12)
    assert rec["modal_masses_kg"][2] == pytest.approx(0.5 * B1.mass_per_length_kg_m * 30.0, rel=1e-12)
    assert Bridge(**P.bridge_fields(rec["bridge"])) == deck
    # the monitor's passage: the train leaves after the last span (the deck's length, not a span's)
    from adm_sim.monitoring.modal_id import PassageTracker

    tracker = PassageTracker()
    tracker.bridge_description(rec)
    assert tracker.span_m == 30.0
    (res,) = bridge_b1.set_parameters([Parameter("spans_m", value="15")])  # one span: B1 itself (sine modes)
    assert res.successful and bridge_b1.bridge == B1 and not bridge_b1.bridge.is_continuous
    (res,) = bridge_b1.set_parameters([Parameter("spans_m", value="")])
    assert res.successful and bridge_b1.bridge == B1
    assert sent[-1]["bridge"]["spans_m"] == [] and sent[-1]["supports_m"] == [0.0, 15.0]
    assert sent[-1]["frequencies_hz"] == B1.frequencies_hz.tolist()


def test_per_span_values_and_n0_on_a_deck(bridge_deck):
    """Per-span EJ and mu reach the spans they name; ``n0_hz`` gives one EJ for every span with that
    first frequency (as ``n0`` in a deck spec)."""
    (res,) = bridge_deck.set_parameters([Parameter("span_mu_kg_m", value="19042,25000")])
    assert res.successful, res.reason
    assert bridge_deck.bridge.span_mu_kg_m == (19042.0, 25000.0)
    zeta = resolve_bridge(DECK_SPEC, continuous=True).damping_ratio  # 1.85 / 100 as the reader divides
    assert bridge_deck.bridge == Bridge.continuous((15.0, 15.0), 2.667e10, (19042.0, 25000.0), zeta, n_modes=3,
                                                   name="deck2")
    (res,) = bridge_deck.set_parameters([Parameter("n0_hz", value=6.0)])
    assert res.successful, res.reason
    assert bridge_deck.bridge.n0_hz == pytest.approx(6.0, rel=1e-12)
    assert len(set(bridge_deck.bridge.span_EJ_Nm2)) == 1


@pytest.mark.parametrize("fixture, name, value, line", [
    ("bridge_b1", "spans_m", "15,x", "spans_m[1]: 'x' is not a number; allowed [1, 150] m"),
    ("bridge_b1", "spans_m", "15,200", "spans_m[1]: 200 m is out of range; allowed [1, 150] m"),
    ("bridge_b1", "spans_m", "10,10,10,10,10,10,10", "spans_m: '10,10,10,10,10,10,10' gives 7 spans; allowed 1..6 spans, "
                                                     "each in [1, 150] m"),
    ("bridge_b1", "spans_m", "150,150", "spans_m: the deck's first frequency is 0.08262 Hz with spans_m = '150,150'; "
                                       "allowed n0 in [0.5, 100] Hz"),
    ("bridge_b1", "span_EJ_Nm2", "1e10", "span_EJ_Nm2: '1e10' gives one value per span; per-span values need spans_m"),
    ("bridge_deck", "span_mu_kg_m", "19042,50", "span_mu_kg_m[1]: 50 kg/m is out of range; allowed [100, 1e+06] kg/m"),
    ("bridge_deck", "span_EJ_Nm2", "1e10,1e10,1e10", "span_EJ_Nm2: '1e10,1e10,1e10' gives 3 values for 2 spans; "
                                                     "allowed one value or one per span (N m^2)"),
    ("bridge_deck", "span_EJ_Nm2", "0.5,2e10", "span_EJ_Nm2[0]: 0.5 N m^2 is out of range; allowed [1, 1e+14] N m^2"),
    ("bridge_deck", "span_m", 40.0, "span_m: 40.0 m and spans_m = '15.0,15.0' both give the length"),
    ("bridge_deck", "spans_m", "10,10,10", "span_mu_kg_m: '19042.0,19042.0' gives 2 values for 3 spans; allowed one "
                                           "value or one per span (kg/m)"),
    ("bridge_deck", "mu_kg_m", 20000.0, "mu_kg_m: 20000.0 kg/m and span_mu_kg_m = '19042.0,19042.0' both give the mass"),
    ("bridge_deck", "response_m", 40.0, "response_m: 40 m is off the deck; allowed 0 (midspan) or 0 < x < 30 m"),
    ("bridge_deck", "response_m", -1.0, "response_m: -1 m is out of range; allowed 0 (midspan) or [0.001, 900] m"),
    ("bridge_deck", "n_modes", 51, "n_modes: 51 is out of range; allowed integer in [1, 50]"),
    ("bridge_deck", "n_modes", 0, "n_modes: 0 is out of range; allowed integer in [1, 50]"),
    ("bridge_b1", "n_modes", 21, "n_modes: 21 is out of range; allowed integer in [1, 20]"),  # one span: as before
    ("bridge_deck", "spans_m", "", "span_EJ_Nm2: '26670000000.0,26670000000.0' gives one value per span; per-span "
                                   "values need spans_m"),
])
def test_bad_deck_parameters_are_refused_in_one_line(request, fixture, name, value, line):
    """Refused at the parameter service with one line naming the parameter, the value, the unit and
    the range; the node keeps its values and its bridge."""
    node = request.getfixturevalue(fixture)
    old, old_bridge = node.get_parameter(name).value, node.bridge
    (res,) = node.set_parameters([Parameter(name, value=value)])
    assert not res.successful
    assert res.reason.startswith(line) and "\n" not in res.reason, res.reason
    assert node.get_parameter(name).value == old and node.bridge is old_bridge


#: Six 30 m spans at n0 = 1.6 Hz: the rule (every mode up to 30 Hz, 1.5 n0 or the third) keeps 22 modes.
DECK22_SPEC = "spans=30/30/30/30/30/30,n0=1.6,mu=10000,zeta_pct=1"


def test_deck_of_more_than_20_modes_starts_with_the_rules_count(ctx):
    """The node takes a deck of up to 50 modes (the registry's deck_n_modes, as ``adm-sim sweep``): the
    22-mode deck starts with its rule's 22 modes, the reader's deck exactly; n_modes set to 50 is
    taken, 51 refused in one line; one span stays at most 20 (checked above)."""
    from adm_sim.nodes.bridge_node import BridgeNode

    node = BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value=DECK22_SPEC)])
    try:
        deck = resolve_bridge(DECK22_SPEC, continuous=True)
        assert deck.n_modes == 22 and node.bridge == deck
        assert node.get_parameter("n_modes").value == 22
        (res,) = node.set_parameters([Parameter("n_modes", value=50)])
        assert res.successful, res.reason
        assert node.bridge.n_modes == 50 and node.bridge.frequencies_hz.size == 50
        np.testing.assert_array_equal(node.bridge.frequencies_hz[:22], deck.frequencies_hz)
        (res,) = node.set_parameters([Parameter("n_modes", value=51)])
        assert not res.successful and res.reason.startswith("n_modes: 51 is out of range; allowed integer in [1, 50]")
        assert node.bridge.n_modes == 50
    finally:
        node.destroy_node()
    # more than 50 in the spec: the reader's refusal, before any node
    with pytest.raises(InputError, match=r"^bridge spec\.n_modes: 51 is out of range; allowed integer in \[1, 50\]$"):
        BridgeNode(context=ctx, parameter_overrides=[Parameter("bridge", value=DECK22_SPEC + ",n_modes=51")])


# ---------------------------------------------------------------- lockstep runs through the graph
@pytest.mark.slow
def test_deck_runs_through_the_graph_equal_the_core(node_procs, ros_domain):
    """Bridge and train nodes in two processes, preset B1: an MLM run of B1 (one span, as before) and
    one at ``response_m = 5`` (``run_sweep``'s ``where``), then ``spans_m = 15,15`` set over the parameter service (a bad deck refused there first), then an
    MLM and a DIM run of the deck: each equals ``run_sweep`` bit for bit (maxima of acceleration and
    deflection at both speeds) and the compiled kernels to 1e-10 relative."""
    node_procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": "B1", **STEP, **SPARSE})
    node_procs.start("train", "adm_sim.nodes.train_node", {"speeds_kmh": "250,300"})
    ice2, opts = load_train("ICE-2"), StepOptions(**STEP)
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        r = d.request_run(model="mlm")
        ref = run_sweep(B1, ice2, "mlm", SPEEDS_KMH, options=opts)
        np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2)
        np.testing.assert_array_equal(r["max_disp_m"], ref.max_disp_m)
        # the response point of one span: run_sweep's where, bit for bit
        d.set_params("bridge", response_m=5.0)
        r = d.request_run(model="mlm")
        ref = run_sweep(B1, ice2, "mlm", SPEEDS_KMH, options=opts, where=5.0)
        np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2)
        d.set_params("bridge", response_m=0.0)
        with pytest.raises(InputError, match=r"^bridge: spans_m\[1\]: 200 m is out of range; allowed \[1, 150\] m"):
            d.set_params("bridge", spans_m="15,200")
        d.set_params("bridge", spans_m="15,15")
        deck = b1_deck()
        for model in ("mlm", "dim"):
            r = d.request_run(model=model)
            ref = run_sweep(deck, ice2, model, SPEEDS_KMH, options=opts)
            np.testing.assert_array_equal(r["speeds_kmh"], SPEEDS_KMH)
            np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2, err_msg=model)
            np.testing.assert_array_equal(r["max_disp_m"], ref.max_disp_m, err_msg=model)
            comp = run_sweep_compiled(deck, ice2, model, SPEEDS_KMH, options=opts)
            np.testing.assert_allclose(r["max_acc_m_s2"], comp.max_acc_m_s2, rtol=1e-10, atol=0)
            # a deck is not the span of its length: the runs differ from B1's
            assert not np.allclose(r["max_acc_m_s2"], run_sweep(B1, ice2, model, SPEEDS_KMH, options=opts).max_acc_m_s2)
        desc = d.description("bridge")
        assert desc["bridge"]["spans_m"] == [15.0, 15.0] and desc["supports_m"] == [0.0, 15.0, 30.0]
        assert desc["frequencies_hz"] == deck.frequencies_hz.tolist()
        check_train_node_refuses_a_span_shorter_than_its_axle_groups(d)
    assert all(p.poll() is None for p in node_procs.procs.values())


def check_train_node_refuses_a_span_shorter_than_its_axle_groups(d):
    """A deck with a 2.5 m span under ICE-2 (bogie wheelbase 3 m), given to the bridge node directly
    (``spans_m`` set over its parameter service: no launcher checked it): the train node refuses the
    run in one line naming the span, the train and the allowed lengths, as ``adm-sim sweep`` does;
    both nodes keep running (the caller's last assertion). On the graph of
    :func:`test_deck_runs_through_the_graph_equal_the_core`: a graph of its own cost a test two more
    node processes."""
    from adm_sim.errors import RunError

    d.set_params("bridge", spans_m="15,2.5")
    with pytest.raises(RunError, match=r"start_run refused: spans\[1\]: 2.5 m is shorter than the longest axle "
                                       r"group of ICE-2 \(bogie wheelbase 3 m\); allowed spans >= 3 m$"):
        d.request_run(model="mlm")


@pytest.mark.slow
def test_deck_of_22_modes_runs_through_the_graph_equal_the_core(node_procs, ros_domain):
    """The six-span deck whose rule keeps 22 modes (more than the 20 the node took before): MLM and
    DIM runs through the graph (bridge and train nodes in two processes) equal ``run_sweep`` of the
    reader's deck bit for bit; the description record carries the 22 frequencies."""
    node_procs.start("bridge", "adm_sim.nodes.bridge_node", {"bridge": DECK22_SPEC, **STEP, **SPARSE})
    node_procs.start("train", "adm_sim.nodes.train_node", {"speeds_kmh": "250,300"})
    deck, ice2, opts = resolve_bridge(DECK22_SPEC, continuous=True), load_train("ICE-2"), StepOptions(**STEP)
    assert deck.n_modes == 22
    with driver_node(ros_domain.domain_id) as d:
        d.wait_for_graph()
        for model in ("mlm", "dim"):
            r = d.request_run(model=model)
            ref = run_sweep(deck, ice2, model, SPEEDS_KMH, options=opts)
            np.testing.assert_array_equal(r["max_acc_m_s2"], ref.max_acc_m_s2, err_msg=model)
            np.testing.assert_array_equal(r["max_disp_m"], ref.max_disp_m, err_msg=model)
        desc = d.description("bridge")
        assert desc["frequencies_hz"] == deck.frequencies_hz.tolist() and len(desc["frequencies_hz"]) == 22
    assert all(p.poll() is None for p in node_procs.procs.values())


# ---------------------------------------------------------------- the launchers
PARAMS = ("bridge:\n  ros__parameters:\n    steps_per_period: 4.0\n    free_vibration_periods: 1.0\n"
          "    beam_every_steps: 32\ntrain:\n  ros__parameters:\n    train: ICE-2\n    model: mlm\n")


def _apexes(path):
    """The support apexes drawn in an ``.rrd`` (each triangle's second vertex)."""
    from rerun.chunk import RrdReader  # noqa: PLC0415  rerun (~0.9 s) in this test only

    for chunk in RrdReader(path).stream():
        if chunk.entity_path == "/" + P.beam_path(part="supports"):
            rb = chunk.to_record_batch()
            name = next(n for n in rb.schema.names if n.endswith("LineStrips2D:strips"))
            return [s[1] for s in rb.column(name).to_pylist()[-1]]
    raise AssertionError("no supports drawn")


@pytest.mark.slow
def test_crossing_runs_a_deck_given_as_its_bridge(tmp_path):
    """``crossing.py --bridge spans=15/15,...`` runs the deck in the graph: its summary equals
    ``run_sweep`` of the reader's deck bit for bit and carries the spans, the supports, the frequencies
    and the modal masses; every beam frame on the recording passes through the three supports
    (deflection 0 there, to round-off) and the rerun view draws the three supports."""
    from adm_sim.recording.mcap_log import read_messages

    params = tmp_path / "deck.yaml"
    params.write_text(PARAMS)
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "crossing.py"), "--params-file", str(params),
                        "--bridge", DECK_SPEC, "--speeds", "250,300", "--out", str(out)],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    deck = resolve_bridge(DECK_SPEC, continuous=True)
    s = json.loads((out / "summary.json").read_text())
    ref = run_sweep(deck, load_train("ICE-2"), "mlm", SPEEDS_KMH, options=StepOptions(**STEP))
    np.testing.assert_array_equal(s["max_acc_m_s2"], ref.max_acc_m_s2)
    np.testing.assert_array_equal(s["max_disp_m"], ref.max_disp_m)
    assert s["spans_m"] == [15.0, 15.0] and s["supports_m"] == [0.0, 15.0, 30.0] and s["span_m"] == 30.0
    assert s["frequencies_hz"] == deck.frequencies_hz.tolist()
    assert s["modal_masses_kg"] == deck.modal_mass_kg.tolist()
    assert "continuous deck of 2 spans" in r.stdout
    frames = 0
    for _topic, _t, msg in read_messages(out / "run.mcap", topics=[P.TOPIC_BEAM]):
        a = np.asarray(msg.data, dtype=float)[1:].reshape(2, -1)
        x, w = a
        np.testing.assert_array_equal(x, beam_grid_m(deck, 21))
        assert np.abs(w[np.isin(x, [0.0, 15.0, 30.0])]).max() <= 1e-12 * max(np.abs(w).max(), 1e-300)
        frames += 1
    assert frames >= 10
    np.testing.assert_array_equal(_apexes(out / "run.rrd"), [[0.0, 0.0], [15.0, 0.0], [30.0, 0.0]])


def test_shipped_deck_params_file_is_the_deck(monkeypatch):
    """ros_ws/params/crossing_deck_2x15.yaml passes the launchers' check and gives two spans of B1."""
    monkeypatch.syspath_prepend(str(ROOT / "launch_scripts"))
    import _supervisor

    from adm_sim.nodes.params import bridge_from_params, bridge_specs

    values = _supervisor.check_inputs(params_file=str(ROOT / "ros_ws" / "params" / "crossing_deck_2x15.yaml"))
    p = {s.name: s.default for s in bridge_specs(B1)} | {k: v for k, v in values["bridge"].items() if k != "bridge"}
    assert bridge_from_params(B1, p) == b1_deck()


@pytest.mark.parametrize("script", ["crossing.py", "calibrate.py"])
def test_launchers_refuse_a_bad_deck_in_one_line(launcher, tmp_path, script):
    """A bad deck from --bridge or from the params file's bridge section: exit 2, one line naming what
    was typed, before any process starts or any folder is created."""
    out = tmp_path / "out"
    cases = [
        (["--bridge", "spans=15/x,EJ=2e10,mu=15000,zeta_pct=1.5"],
         "error: bridge spec.spans[1]: 'x' is not a number; allowed [1, 150] m"),
        (["--bridge", DECK22_SPEC + ",n_modes=51"], "error: bridge spec.n_modes: 51 is out of range; allowed integer "
                                                    "in [1, 50]"),
    ]
    modes = tmp_path / "modes.yaml"
    modes.write_text('bridge:\n  ros__parameters:\n    spans_m: "15,15"\n    n_modes: 51\n')
    cases.append((["--params-file", str(modes)], f"error: --params-file {str(modes)!r}: bridge: n_modes: 51 is out of "
                                                 "range; allowed integer in [1, 50]"))
    cases.append((["--bridge", "spans=15/2.5,EJ=2e10,mu=15000,zeta_pct=1.5", "--train", "ICE-2"],
                  "error: bridge node: spans[1]: 2.5 m is shorter than the longest axle group of ICE-2 (bogie wheelbase "
                  "3 m); allowed spans >= 3 m"))
    one = tmp_path / "one.yaml"
    one.write_text("bridge:\n  ros__parameters:\n    n_modes: 21\n")
    cases.append((["--params-file", str(one)], "error: bridge node: n_modes: 21 is out of range; allowed integer in "
                                               "[1, 20]"))
    bad = tmp_path / "bad.yaml"
    bad.write_text('bridge:\n  ros__parameters:\n    spans_m: "15,200"\n')
    cases.append((["--params-file", str(bad)], "error: bridge node: spans_m[1]: 200 m is out of range; allowed [1, 150] m"))
    two = tmp_path / "two.yaml"
    two.write_text('bridge:\n  ros__parameters:\n    spans_m: "15,15"\n    span_m: 20.0\n')
    cases.append((["--params-file", str(two)], "error: bridge node: span_m: 20.0 m and spans_m = '15,15' both give "
                                                "the length"))
    for argv, line in cases:
        code, stdout, stderr = launcher(script, argv + ["--out", str(out)])
        lines = stderr.strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith(line), (argv, stderr)
        assert "Traceback" not in stderr and not out.exists()


@pytest.mark.slow
def test_calibrate_launch_on_a_deck_is_the_in_process_calibration(tmp_path):
    """``calibrate.py --bridge spans=15/15,...`` (255..279 km/h every 3 km/h, the coarse steps): the
    calibration node rebuilds the deck from the bridge's description record, runs every sweep at the
    middle of each span (the bridge's ``response_m``) and takes the larger maxima, so its Δζ, status
    and peaks equal ``adm-calib calibrate``'s on the numpy stepper bit for bit (the compiled kernels:
    to the root tolerance's digits); the summary names the deck's spans, frequencies and modal masses.
    The range holds the deck's resonance inside (MLM peak 261 km/h, DIM 261 km/h: every phase runs,
    Δζ is found) and starts at 255 km/h, not 240: the slowest speed sets the step, and the numpy
    reference runs every DIM lane (3.7 s for 240..300, 1.5 s here)."""
    from adm_calib.calibrate import CalibrationOptions, calibrate

    params = tmp_path / "deck.yaml"
    params.write_text("bridge:\n  ros__parameters:\n    steps_per_period: 4.0\n    free_vibration_periods: 1.0\n")
    out = tmp_path / "cal"
    r = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "calibrate.py"), "--params-file", str(params),
                        "--bridge", DECK_SPEC, "--speeds", "255:279:3", "--out", str(out), "--quiet", "--no-rrd"],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads((out / "summary.json").read_text())
    deck, ice2 = resolve_bridge(DECK_SPEC, continuous=True), load_train("ICE-2")

    # adm-calib calibrate's numbers on the numpy stepper: each sweep at the middle of either span, the larger
    ref = calibrate(deck, ice2, np.arange(255.0, 280.0, 3.0),
                    options=CalibrationOptions(dim_grid="window", step=StepOptions(**STEP)), backend="numpy").to_dict()
    assert got["status"] == ref["status"] and got["bridge_description"] == deck.describe()
    assert got["delta_zeta_vbi_pct"] == ref["delta_zeta_vbi_pct"] is not None
    assert got["mlm_peak"] == ref["mlm_peak"] and got["dim_peak"] == ref["dim_peak"]
    assert got["co_simulation"]["runs"] % 2 == 0  # two runs (one per span's middle) for every sweep
    compiled = calibrate(deck, ice2, np.arange(255.0, 280.0, 3.0),
                         options=CalibrationOptions(dim_grid="window", step=StepOptions(**STEP)))
    assert f"{got['delta_zeta_vbi_pct']:.4f}" == f"{100 * compiled.delta_zeta_vbi:.4f}"
    assert got["spans_m"] == [15.0, 15.0] and got["supports_m"] == [0.0, 15.0, 30.0]
    assert got["frequencies_hz"] == deck.frequencies_hz.tolist()
    assert got["modal_masses_kg"] == deck.modal_mass_kg.tolist()
