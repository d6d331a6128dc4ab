"""One home per rule: the ROS-free protocol (topics, records, phases, rerun entities) and the limits.

Independent references: the EN 1990 A2.4.4.2.1(4)P values typed from the standard, the paper's
Section 3.3 speed range built by ``np.arange``, the Δζ bounds at their exact edges, and a source scan
that finds any topic name or entity path written outside :mod:`adm_sim.protocol`.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from adm_sim import fields, limits
from adm_sim import protocol as P
from adm_sim.errors import InputError

ROOT = Path(__file__).resolve().parents[2]


# ---------------------------------------------------------------- layering


@pytest.mark.slow
def test_protocol_and_limits_import_neither_rerun_nor_mcap():
    """The recording libraries stay out of the shared tables (that nothing below the nodes loads rclpy
    is tests/house/test_layers.py's ``test_nothing_below_the_nodes_loads_rclpy``)."""
    code = ("import sys, adm_sim.protocol, adm_sim.limits; "
            "print(sorted(m for m in ('rerun', 'mcap', 'mcap_ros2') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


# ---------------------------------------------------------------- topics and entities: one table


def _blueprint_views():
    pytest.importorskip("rerun")
    from adm_sim.recording.rerun_blueprint import default_blueprint

    def walk(container):
        for x in container.contents:
            if hasattr(x, "origin"):
                yield x
            else:
                yield from walk(x)

    return list(walk(default_blueprint(15.0).root_container))


def test_every_blueprint_view_shows_an_entity_of_the_protocol_table():
    views = _blueprint_views()
    assert len(views) == 9
    roots = set(P.ENTITIES.values())
    for v in views:
        assert P.is_entity(str(v.origin)), v.origin
    # each default-view root is shown by a view of its own: nothing logged is left without a view
    shown = {str(v.origin) for v in views}
    assert roots - shown == {P.ENTITIES[k] for k in ("topics", "diagnostics", "metadata")}


def test_entity_paths_lie_below_the_roots():
    assert P.acceleration_path(3) == "runs/acceleration/run_03"
    assert P.beam_path(12, "peak_axles") == "runs/beam/run_12/peak_axles"
    assert P.beam_path(part="supports") == "runs/beam/supports"
    assert P.sweep_trial_path(P.PHASE_ROOT_SEARCH, 7) == "sweep/trials/root_search/07"
    assert P.sweep_curve_path("DIM", trials=True) == "sweep/trials/DIM"
    assert P.delta_zeta_path(P.PHASE_BRACKETING) == "calibration/delta_zeta_pct/bracketing"
    assert P.peak_path("dim") == "calibration/peak_m_s2/dim"
    assert not P.is_entity("runsx/acceleration") and not P.is_entity("sweep")


def test_topic_table_holds_every_topic_the_logger_and_the_recorder_read():
    assert P.RUN_LOGGER_TOPICS <= set(P.TOPICS)
    assert set(P.OPENING_TOPICS) <= P.RUN_LOGGER_TOPICS
    assert set(P.DESCRIPTION_TOPICS.values()) <= set(P.TOPICS)
    for name, (typ, qos, _pub) in P.TOPICS.items():
        assert re.fullmatch(r"/[a-z_]+(/[a-z_]+)*", name), name
        assert re.fullmatch(r"[a-z_]+/msg/[A-Za-z0-9]+", typ), typ
        assert qos in "CXMLH", (name, qos)
    assert len({n for n in P.TOPICS}) == 20


def test_the_driver_records_only_topics_of_the_table():
    pytest.importorskip("rclpy")
    from adm_sim.nodes.driver import RECORDED

    for topic, cls in RECORDED:
        typ = P.TOPICS[topic][0]
        assert typ == f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}", (topic, typ, cls)


#: String literals that spell a topic name or an entity path (written outside the protocol).
_TOPIC_OR_ENTITY = re.compile(
    r"""(?<![\w.])[fr]?(["'])(/adm\b[^"']*|/clock|/diagnostics|/train/start_run|"""
    r"""(?:runs|sweep|calibration)/(?:acceleration|beam|info|curves|trials|delta_zeta_pct|peak_m_s2|result)"""
    r"""[^"']*|(?:topics|diagnostics|metadata)/[^"']*)\1""")
#: Literals that only look like one: an example in an error message (not a topic of the graph).
_NOT_A_NAME = {("src/adm_sim/recording/mcap_write.py", "'/adm/x'")}


def test_no_topic_name_or_entity_path_is_written_outside_the_protocol():
    hits = []
    files = [*sorted((ROOT / "src").rglob("*.py")), *sorted((ROOT / "launch_scripts").glob("*.py"))]
    for path in files:
        if path.name == "protocol.py":
            continue
        for i, line in enumerate(path.read_text().splitlines(), start=1):
            if line.lstrip().startswith((">>>", "...")):  # a usage example in a docstring
                continue
            for m in _TOPIC_OR_ENTITY.finditer(line):
                if (str(path.relative_to(ROOT)), m.group(0)) not in _NOT_A_NAME:
                    hits.append(f"{path.relative_to(ROOT)}:{i}: {m.group(0)}")
    assert hits == []


def test_the_scan_finds_a_literal_topic_and_an_entity_path():
    """The scan of the test above can fail: it sees the literals the protocol replaced."""
    lines = ['pub = node.create_publisher(String, "/adm/run/status", qos)', "rr.log('runs/beam/supports', x)",
             'if ch.topic == "/clock":', 'rr.log(f"sweep/trials/{root}/{n:02d}", a)',
             'rr.log(f"diagnostics/{name}", log)']
    assert [bool(_TOPIC_OR_ENTITY.search(s)) for s in lines] == [True] * len(lines)
    assert not _TOPIC_OR_ENTITY.search('raise InputError(f"topic: {t!r} is not absolute (e.g. \'/x\')")')
    assert not _TOPIC_OR_ENTITY.search('if kind == "metadata":')


# ---------------------------------------------------------------- records


def test_records_round_trip_through_json():
    setup = P.setup_record(4, "dim", "ICE-2", np.array([200.0, 250.0]), np.array([200 / 3.6, 250 / 3.6]), 200.0,
                           np.array([0.0, 3.0]), np.array([1.6e5, 1.6e5]), np.array([1800.0, 1800.0]))
    got = P.decode(P.encode(setup))
    assert got["speeds_kmh"] == [200.0, 250.0] and got["wheel_mass_kg"] == [1800.0, 1800.0]
    assert P.decode(P.encode(P.setup_record(5, "mlm", "ICE-2", [200.0], [55.5], 1.0, [0.0], [1.0], None)))[
        "wheel_mass_kg"] is None
    ready = P.ready_record(4, ds_m=0.05, n_steps=1000, span_m=15.0, n_lanes=2, t0_s=1.5)
    assert not P.is_rejected(ready) and P.is_rejected(P.ready_error(4, "delta_zeta_lanes: 3 values for 2 lanes"))
    st = P.decode(P.encode(P.status_record(P.BRIDGE_NODE, 4, P.STARTED, model="dim", n_lanes=2)))
    assert list(st) == ["node", "run_id", "state", "model", "n_lanes"]
    assert P.is_bridge_start(st) and not P.is_failure(st)
    failed = P.status_record(P.TRAIN_NODE, 4, P.FAILED, message="x")
    assert P.is_failure(failed) and P.is_failure(failed, 4) and not P.is_failure(failed, 5)
    assert not P.is_bridge_start(P.status_record(P.TRAIN_NODE, 4, P.STARTED))
    assert not P.is_bridge_start(P.status_record(P.BRIDGE_NODE, None, P.STARTED))


# ---------------------------------------------------------------- run phases


@pytest.mark.parametrize("model, dz, lanes, phase", [
    ("dim", 0.0, "", P.PHASE_DIM),
    ("DIM", 0.01, "0.0,0.01", P.PHASE_DIM),
    ("mlm", 0.0, "", P.PHASE_MLM_ZETA),
    ("mlm", 0.01, "0.0,0.0", P.PHASE_MLM_ZETA),          # the lanes replace delta_zeta
    ("mlm", 0.0055, "", P.PHASE_MLM_ZETA_DZ),
    ("mlm", 0.0, [0.0055, 0.0055], P.PHASE_MLM_ZETA_DZ),
    ("mlm", 0.0, "-0.005, 0.0 ,0.01", P.PHASE_BRACKETING),
])
def test_plain_run_phase_is_named_by_the_request(model, dz, lanes, phase):
    """A run outside a calibration is named by the parameters it runs with (model, the bridge's
    delta_zeta and delta_zeta_lanes), never by its result's arrays; a root search is a calibration's."""
    assert P.plain_run_phase(model, dz, lanes) == phase


def test_request_record_carries_the_phase_with_the_run_id():
    st = P.decode(P.encode(P.request_record(P.CALIBRATION_NODE, 7, "mlm", P.PHASE_BRACKETING, "MLM trial")))
    assert st == {"node": "calibration", "run_id": 7, "state": "requested", "model": "mlm", "phase": "bracketing",
                  "label": "MLM trial"}
    assert P.is_request(st) and not P.is_bridge_start(st) and not P.is_failure(st)
    assert not P.is_request(P.status_record(P.BRIDGE_NODE, 7, P.STARTED))
    assert P.PHASE_UNKNOWN not in P.PHASES and set(P.SWEEP_CURVE_NAMES) | set(P.TRIAL_PHASES) == {
        *P.PHASES, P.PHASE_UNKNOWN}


def test_calibration_node_and_rerun_logger_name_the_same_phases():
    pytest.importorskip("rclpy")
    pytest.importorskip("rerun")
    from adm_calib.nodes.calibration_node import PHASE_LABELS
    from adm_sim.recording import rerun_log as rl

    assert set(PHASE_LABELS) == set(P.PHASES)
    from adm_calib.lanes import PHASES as CALIBRATION_REQUEST_PHASES

    # every phase a calibration request carries has its run phase, and nothing else is mapped
    assert set(P.CALIBRATION_PHASES) == set(CALIBRATION_REQUEST_PHASES)
    assert set(P.CALIBRATION_PHASES.values()) == set(P.PHASES)
    assert {p: rl.run_kind(p) for p in (*P.PHASES, P.PHASE_UNKNOWN)} == {
        P.PHASE_DIM: rl.DIM, P.PHASE_MLM_ZETA: rl.MLM_ZETA, P.PHASE_MLM_ZETA_DZ: rl.MLM_ZETA_DZ,
        P.PHASE_BRACKETING: rl.BRACKETING, P.PHASE_ROOT_SEARCH: rl.ROOT_SEARCH, P.PHASE_UNKNOWN: rl.UNKNOWN}
    with pytest.raises(InputError, match=r"^phase: 'ladder' is not a run phase; allowed dim, "):
        rl.run_kind("ladder")  # a calibration request's phase must be mapped first (CALIBRATION_PHASES)


# ---------------------------------------------------------------- limits


def test_deck_acceleration_limits_are_those_of_en_1990_a2_4_4_2_1():
    # EN 1990 A2.4.4.2.1(4)P: gamma_bt = 3.5 m/s^2 ballasted, gamma_df = 5 m/s^2 direct fastened, as the
    # lookup answers them for every spelling (the check's verdict on 3.5: test_check's JSON test)
    assert [limits.acc_limit_m_s2(t) for t in ("ballasted", "direct_fastening", "direct")] == [3.5, 5.0, 5.0]
    assert limits.check_track_type("track_type", "direct_fastening") == "direct_fastening"
    assert limits.check_track_type("--track", "direct", aliases=True) == "direct_fastening"
    with pytest.raises(InputError, match=r"^track_type: 'direct' is not allowed; allowed ballasted or "
                                         r"direct_fastening$"):
        limits.check_track_type("track_type", "direct")
    with pytest.raises(InputError, match=r"^--track: 'slab' is not allowed; allowed ballasted or direct_fastening$"):
        limits.check_track_type("--track", "slab", aliases=True)


def test_default_speeds_are_section_3_3():
    v = limits.default_speeds_kmh()
    np.testing.assert_array_equal(v, np.arange(160.0, 351.0, 1.0))  # 160..350 km/h every 1 km/h
    from adm_sim.inputs.speeds import parse_speeds

    np.testing.assert_array_equal(parse_speeds(limits.DEFAULT_SPEEDS), v)
    v[0] = 0.0
    assert limits.default_speeds_kmh()[0] == 160.0  # a new array each call


@pytest.mark.parametrize("zeta", [0.0, 0.0185, 0.05])
def test_delta_zeta_range_edges(zeta):
    assert fields.check_delta_zeta("delta_zeta", -zeta, zeta) == -zeta  # total damping 0
    assert fields.check_delta_zeta("delta_zeta", 0.2, zeta) == 0.2
    assert fields.check_delta_zeta_pct("delta_zeta_pct", -100 * zeta, zeta) == -100 * zeta
    assert fields.check_delta_zeta_pct("delta_zeta_pct", 20.0, zeta) == 20.0
    with pytest.raises(InputError, match=r"^delta_zeta: 0\.2001 - \(fraction\) is out of range; allowed "):
        fields.check_delta_zeta("delta_zeta", 0.2001, zeta)
    with pytest.raises(InputError, match=r"^--delta-zeta-pct: 20\.01 % is out of range; allowed "):
        fields.check_delta_zeta_pct("--delta-zeta-pct", 20.01, zeta)
    below = -zeta - 1e-4
    with pytest.raises(InputError, match=r"out of range"):
        fields.check_delta_zeta("delta_zeta", below, zeta)
    with pytest.raises(InputError, match=r"out of range"):
        fields.check_delta_zeta_pct("delta_zeta_pct", 100 * below, zeta)
    # the calibration's bracketing ladder ends exactly on the registry's top, 0.2, which the check accepts
    from adm_calib.damping_root import _ladder

    top = _ladder(zeta)[-1]
    assert top == 0.2 and fields.check_delta_zeta("delta_zeta", top, zeta) == top


def test_driver_lines_round_trip_and_other_lines_pass_through():
    line = P.driver_line("run", {"run_id": 3, "state": "done", "max_acc_m_s2": 2.25, "label": "MLM zeta"})
    assert line == '@run {"run_id": 3, "state": "done", "max_acc_m_s2": 2.25, "label": "MLM zeta"}'
    assert P.parse_driver_line(line) == ("run", {"run_id": 3, "state": "done", "max_acc_m_s2": 2.25,
                                                 "label": "MLM zeta"})
    assert P.parse_driver_line("[INFO] [bridge]: run 3 done") == (None, "[INFO] [bridge]: run 3 done")


def test_calibration_hands_on_the_phase_of_every_sweep():
    """What the calibration sends, against what it does: a calibration over closed-form curves
    (MLM peak 3 ζ/(ζ + Δζ) m/s², DIM peak 2.4 m/s², Lorentzian in speed) runs the MLM ζ curve, the
    DIM, the bracketing ladder (several Δζ on the window's lanes), the root search (one Δζ on fewer
    lanes than the full range) and the adapted curve (one Δζ on every lane), in that order; the phase
    its hook is handed, mapped by ``CALIBRATION_PHASES``, names each call so, and the root is
    Δζ = ζ (3 / 2.4 - 1)."""
    from adm_calib.calibrate import calibrate
    from adm_sim.inputs.bridges import resolve_bridge
    from adm_sim.inputs.train_files import load_train

    bridge, train = resolve_bridge("B1"), load_train("ICE-2")
    zeta = bridge.damping_ratio
    v_all = np.arange(200.0, 301.0, 1.0)
    phases = []

    def hook(model, speeds, dz, step, phase):
        dz = np.broadcast_to(np.asarray(dz, dtype=float), np.shape(speeds))
        run_phase = P.CALIBRATION_PHASES[phase]
        # the run's own shape agrees with the phase it was handed (independent of the mapping)
        expected_shape = {P.PHASE_DIM: model == "dim",
                          P.PHASE_MLM_ZETA: model == "mlm" and np.all(dz == 0.0),
                          P.PHASE_MLM_ZETA_DZ: model == "mlm" and np.unique(dz).size == 1 and np.size(speeds) == v_all.size,
                          P.PHASE_BRACKETING: model == "mlm" and np.unique(dz).size > 1,
                          P.PHASE_ROOT_SEARCH: model == "mlm" and np.unique(dz).size == 1 and np.size(speeds) < v_all.size}
        assert expected_shape[run_phase], (phase, model, np.unique(dz), np.size(speeds))
        phases.append(run_phase)
        shape = 1.0 / (1.0 + ((np.asarray(speeds) - 250.0) / 8.0) ** 2)
        peak = 2.4 if model == "dim" else 3.0 * zeta / (zeta + dz)
        return 0.2 + (peak - 0.2) * shape

    res = calibrate(bridge, train, v_all, sweep=hook)
    assert res.status == "ok", res.message
    np.testing.assert_allclose(res.delta_zeta_vbi, zeta * (3.0 / 2.4 - 1.0), rtol=1e-4)
    order = [P.PHASE_MLM_ZETA, P.PHASE_DIM, P.PHASE_BRACKETING, P.PHASE_ROOT_SEARCH, P.PHASE_MLM_ZETA_DZ]
    runs = [p for i, p in enumerate(phases) if i == 0 or p != phases[i - 1]]  # consecutive repeats merged
    assert runs == order, phases


def test_docs_topic_table_matches_the_protocol():
    """docs/ros.md lists every topic of the protocol with its message type, and nothing else
    (besides the start-run service)."""
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "ros.md").read_text()
    rows = dict(re.findall(r"^\| `(/[^`]+)` \| `?([^`|]+?)`? \|", doc, re.M))
    topics = {n: t for n, t in rows.items() if n != P.SERVICE_START_RUN}
    assert set(topics) == set(P.TOPICS)
    for name, typ in topics.items():
        assert typ.strip().replace("/msg/", "/") == P.TOPICS[name][0].replace("/msg/", "/"), name


def test_ack_counter_acknowledges_first_every_window_and_whole():
    """An opted-in client's acknowledgements: its first message, every ACK_EVERY, and the run's last
    (the final progress record's count over the client's topics), then it counts from 0 again."""
    from adm_sim import protocol as P

    c = P.AckCounter("/mon", topics=(P.TOPIC_ACCEL,))
    acks = [c.count() for _ in range(100)]
    sent = [a["received"] for a in acks if a is not None]
    assert sent == [1, 1 + P.ACK_EVERY, 1 + 2 * P.ACK_EVERY, 1 + 3 * P.ACK_EVERY]
    assert all(a["topics"] == [P.TOPIC_ACCEL] and a["node"] == "/mon" for a in acks if a)
    samples = {t: 7 for t in P.SAMPLE_TOPICS}
    samples[P.TOPIC_ACCEL] = 103
    assert c.final({"run_id": 4, "final": False, "samples": samples}) is None
    assert c.final({"run_id": 4, "final": True, "samples": samples}) is None  # 100 of 103: not whole
    assert [c.count() for _ in range(2)] == [None, None]
    last = c.count()
    assert last == {"node": "/mon", "run_id": 4, "received": 103, "topics": [P.TOPIC_ACCEL]}
    assert c.runs == {4: (103, 103)} and c.received == 0
    assert c.count()["received"] == 1  # the next run's first message
    c.final({"run_id": 5, "final": True, "samples": samples})
    c.started(6)  # run 5 never came whole: booked with what came
    assert c.runs[5] == (1, 103) and c.received == 0
    with pytest.raises(ValueError, match="allowed a non-empty subset"):
        P.AckCounter("/mon", topics=("/adm/run/status",))
