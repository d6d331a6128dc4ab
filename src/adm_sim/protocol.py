"""The adm-sim wire protocol, free of ROS: topic names, JSON records, run phases, rerun entities.

Everything the bridge, train, driver and calibration nodes, the MCAP recorder, the rerun logger,
its blueprint and ``replay.py`` exchange by name lives here, once; nodes turn these names and
records into ROS messages (:mod:`adm_sim.nodes.common`), the rest reads them back. This module
imports only the standard library and numpy (a test asserts that ``rclpy`` stays out).

Topics (:data:`TOPICS`: name -> message type, QoS class C control / X exchange / M monitor /
L latched, publisher; docs/ros.md, section "Topics", is the reference for their layouts)::

    /adm/run/setup      train -> bridge   JSON :func:`setup_record`
    /adm/run/ready      bridge -> train   JSON :func:`ready_record` / :func:`ready_error`
    /adm/run/status     bridge, train,    JSON :func:`status_record` (state started/done/failed;
                        driver            the driver's requested: :func:`request_record`, the phase)
    /adm/run/result     bridge            rows :data:`RESULT_ROWS` x lane
    /adm/exchange/*     lockstep messages (header of :data:`EXCHANGE_HEADER_LEN` doubles)
    /adm/midspan/*, /adm/beam/*, /adm/progress, /clock, /diagnostics: monitoring
    /adm/{bridge,train}/description   JSON, latched
    /adm/calibration/{iteration,result}

Run phases (:data:`PHASES`): which part of the Section 4 calibration a run belongs to. The phase
is handed on, never read from the run's arrays: the calibration names it with every lane request
(:mod:`adm_calib.lanes`), the calibration node maps it with :data:`CALIBRATION_PHASES`, a plain
crossing or sweep is named by what it asks for (:func:`plain_run_phase`); the driver publishes it
with the run id in its ``requested`` status record (:func:`request_record`, recorded in the MCAP)
and hands it to the rerun logger. A recording made before the phase was recorded replays with
:data:`PHASE_UNKNOWN`.

Rerun (:data:`ENTITIES`, :data:`TIMELINES`): the entity roots the logger writes below and the
blueprint's views show, and the timeline names.
"""

from __future__ import annotations

import json
import re

import numpy as np

from adm_sim.errors import InputError

# ---------------------------------------------------------------------- nodes and services
BRIDGE_NODE = "bridge"
TRAIN_NODE = "train"
CALIBRATION_NODE = "calibration"
DRIVER_NODE = "driver"  # a plain run's driver (the calibration node is a driver too)
#: The train node's ``~/start_run`` service (``std_srvs/Trigger``) as the driver calls it.
SERVICE_START_RUN = f"/{TRAIN_NODE}/start_run"

# ---------------------------------------------------------------------- topics
NS = "/adm"
TOPIC_SETUP = f"{NS}/run/setup"            # train -> bridge, std_msgs/String (JSON)
TOPIC_READY = f"{NS}/run/ready"            # bridge -> train, std_msgs/String (JSON)
TOPIC_RAIL = f"{NS}/exchange/rail"         # bridge -> train, Float64MultiArray
TOPIC_FORCES = f"{NS}/exchange/forces"     # train -> bridge (DIM), Float64MultiArray
TOPIC_AXLE_BLOCK = f"{NS}/exchange/axle_block"  # train -> bridge (MLM), Float64MultiArray
TOPIC_RESULT = f"{NS}/run/result"          # bridge, Float64MultiArray (quantity x lane)
TOPIC_STATUS = f"{NS}/run/status"          # bridge/train, std_msgs/String (JSON)
TOPIC_ACCEL = f"{NS}/midspan/accel"        # bridge, geometry_msgs/AccelStamped
TOPIC_STATE = f"{NS}/midspan/state"        # bridge, Float64MultiArray (lane x [disp, acc])
BEAM_NS = f"{NS}/beam"
TOPIC_BEAM = f"{BEAM_NS}/deflection"       # bridge, Float64MultiArray (2 x points)
TOPIC_AXLES = f"{BEAM_NS}/axles"           # bridge, Float64MultiArray (2 x axles on)
TOPIC_PROGRESS = f"{NS}/progress"          # bridge, std_msgs/String (JSON)
TOPIC_BRIDGE_DESC = f"{NS}/bridge/description"  # bridge, std_msgs/String (JSON), latched
TOPIC_TRAIN_DESC = f"{NS}/train/description"    # train, std_msgs/String (JSON), latched
TOPIC_DIAGNOSTICS = "/diagnostics"
TOPIC_CLOCK = "/clock"
TOPIC_CAL_ITERATION = f"{NS}/calibration/iteration"  # calibration, Float64MultiArray
TOPIC_CAL_RESULT = f"{NS}/calibration/result"        # calibration, std_msgs/String (JSON)
TOPIC_ACK = f"{NS}/run/ack"                # recorder -> bridge, std_msgs/String (JSON): flow control
TOPIC_SUMMARY = f"{NS}/run/summary"        # bridge, diagnostic_msgs/DiagnosticStatus, latched


def relative(name: str) -> str:
    """The name a node creates its publisher, subscription or client with: relative (no leading
    ``/``), so that a namespace (``--ros-args -r __ns:=/b3``) moves the whole graph
    (``/b3/adm/run/status``, ``/b3/clock``, ``/b3/train/start_run``). The names above are those
    of the default namespace; recordings store them so (:mod:`adm_sim.recording.mcap_log`)."""
    return name.lstrip("/")

#: A namespace token (rcl's rule: letters, digits and ``_``, not starting with a digit).
_NS_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def check_namespace(text, option="--namespace"):
    """``text`` as an absolute ROS 2 namespace (``b3`` -> ``/b3``, ``/site/b3`` kept; ``/`` or empty:
    the root, ``/``), else :class:`~adm_sim.errors.InputError` naming ``option``, the value and the
    rule (rcl's: ``/``-separated tokens of letters, digits and ``_``, none starting with a digit,
    at most 255 characters)."""
    raw = str(text).strip()
    if raw in ("", "/"):
        return "/"
    ns = raw if raw.startswith("/") else "/" + raw
    tokens = ns[1:].split("/")
    if len(ns) > 255 or not all(_NS_TOKEN.fullmatch(t) for t in tokens):
        raise InputError(f"{option}: {text!r} is not a valid ROS 2 namespace; allowed '/'-separated names of "
                         f"letters, digits and '_', none starting with a digit or empty (e.g. /b3 or /site_1/b3), "
                         f"at most 255 characters", field=option)
    return ns


#: Description topic of the ``bridge`` and ``train`` node.
DESCRIPTION_TOPICS = {BRIDGE_NODE: TOPIC_BRIDGE_DESC, TRAIN_NODE: TOPIC_TRAIN_DESC}

#: Every topic: ``name -> (message type, QoS class, publisher)``; QoS classes: ``C`` control
#: (reliable, deep), ``X`` exchange (reliable, lockstep), ``M`` monitor (reliable, deepest),
#: ``L`` latched (transient local, last value), ``H`` history (transient local, the last
#: :data:`SUMMARY_HISTORY`).
TOPICS = {
    TOPIC_SETUP: ("std_msgs/msg/String", "C", TRAIN_NODE),
    TOPIC_READY: ("std_msgs/msg/String", "C", BRIDGE_NODE),
    TOPIC_RAIL: ("std_msgs/msg/Float64MultiArray", "X", BRIDGE_NODE),
    TOPIC_FORCES: ("std_msgs/msg/Float64MultiArray", "X", TRAIN_NODE),
    TOPIC_AXLE_BLOCK: ("std_msgs/msg/Float64MultiArray", "X", TRAIN_NODE),
    TOPIC_RESULT: ("std_msgs/msg/Float64MultiArray", "L", BRIDGE_NODE),
    TOPIC_STATUS: ("std_msgs/msg/String", "C", f"{BRIDGE_NODE}, {TRAIN_NODE}, {DRIVER_NODE} / {CALIBRATION_NODE}"),
    TOPIC_ACCEL: ("geometry_msgs/msg/AccelStamped", "M", BRIDGE_NODE),
    TOPIC_STATE: ("std_msgs/msg/Float64MultiArray", "M", BRIDGE_NODE),
    TOPIC_BEAM: ("std_msgs/msg/Float64MultiArray", "M", BRIDGE_NODE),
    TOPIC_AXLES: ("std_msgs/msg/Float64MultiArray", "M", BRIDGE_NODE),
    TOPIC_PROGRESS: ("std_msgs/msg/String", "M", BRIDGE_NODE),
    TOPIC_BRIDGE_DESC: ("std_msgs/msg/String", "L", BRIDGE_NODE),
    TOPIC_TRAIN_DESC: ("std_msgs/msg/String", "L", TRAIN_NODE),
    TOPIC_DIAGNOSTICS: ("diagnostic_msgs/msg/DiagnosticArray", "M", f"{BRIDGE_NODE}, {CALIBRATION_NODE}"),
    TOPIC_CLOCK: ("rosgraph_msgs/msg/Clock", "M", BRIDGE_NODE),
    TOPIC_CAL_ITERATION: ("std_msgs/msg/Float64MultiArray", "C", CALIBRATION_NODE),
    TOPIC_CAL_RESULT: ("std_msgs/msg/String", "L", CALIBRATION_NODE),
    TOPIC_ACK: ("std_msgs/msg/String", "C", f"{DRIVER_NODE} / {CALIBRATION_NODE}"),
    TOPIC_SUMMARY: ("diagnostic_msgs/msg/DiagnosticStatus", "H", BRIDGE_NODE),
}
#: Passages the per-passage summary keeps for a late or lagging client (QoS class ``H``: transient
#: local, this history depth).
SUMMARY_HISTORY = 1000

# ---------------------------------------------------------------------- flow control
#: Topics whose messages the bridge counts per run (``samples`` of its final progress record and
#: of its ``done``): every monitoring message of a run. A recorder acknowledges how many of them
#: it has written (:func:`ack_record`); the bridge never runs more than :data:`FLOW_WINDOW` of
#: them ahead of the slowest acknowledging recorder, and publishes ``/adm/run/result`` and ``done``
#: only once every recorder has acknowledged all of them.
SAMPLE_TOPICS = (TOPIC_ACCEL, TOPIC_STATE, TOPIC_BEAM, TOPIC_AXLES, TOPIC_CLOCK, TOPIC_PROGRESS, TOPIC_DIAGNOSTICS)
#: Messages (over :data:`SAMPLE_TOPICS`) a bridge may publish beyond the last acknowledgement.
FLOW_WINDOW = 512
#: A recorder acknowledges after every this many messages (and at the run's last one).
ACK_EVERY = 32
#: Status name of the bridge's ``/diagnostics`` (a run as specified: OK / WARN / ERROR).
DIAG_NAME = "adm_sim/bridge: deck acceleration"
#: Status name of a numerical trial's ``/diagnostics`` (:data:`TRIAL_PHASES`): never above WARN.
DIAG_TRIAL_NAME = "adm_sim/bridge: deck acceleration (numerical trial)"
#: Status name of the per-passage summary (``/adm/run/summary``).
SUMMARY_NAME = "adm_sim/bridge: passage summary"

#: Topics drawn by the rerun logger (:class:`adm_sim.recording.rerun_log.RunLogger`), live and in
#: ``replay.py``; ``/clock`` and ``/adm/midspan/state`` (every lane) are read but not drawn.
RUN_LOGGER_TOPICS = frozenset({
    TOPIC_BRIDGE_DESC, TOPIC_TRAIN_DESC, TOPIC_STATUS, TOPIC_ACCEL, TOPIC_BEAM, TOPIC_AXLES, TOPIC_RESULT,
    TOPIC_CAL_ITERATION, TOPIC_CAL_RESULT, TOPIC_PROGRESS, TOPIC_STATE, TOPIC_CLOCK})
#: Topics that open or describe a run: among records of one log time they go first in a replay.
OPENING_TOPICS = (TOPIC_BRIDGE_DESC, TOPIC_TRAIN_DESC, TOPIC_STATUS)

# ---------------------------------------------------------------------- array layouts
#: Doubles before the axle indices of an exchange message: ``run_id, k, stage, n``.
EXCHANGE_HEADER_LEN = 4
#: ``/adm/run/result`` rows (quantity x lane).
RESULT_ROWS = ("speed_kmh", "max_acc_m_s2", "max_disp_m", "delta_zeta")
#: ``/adm/calibration/iteration`` values.
ITERATION_FIELDS = ("iteration", "delta_zeta_pct", "mlm_peak_m_s2", "dim_peak_m_s2")

# ---------------------------------------------------------------------- JSON records
#: ``state`` of a status record; ``requested`` is the driver's (:func:`request_record`).
STARTED, DONE, FAILED, REQUESTED = "started", "done", "failed", "requested"
RUN_STATES = (STARTED, DONE, FAILED, REQUESTED)


def encode(record: dict) -> str:
    """A record as the ``data`` of a ``std_msgs/String`` (JSON)."""
    return json.dumps(record)


def decode(text: str) -> dict:
    """The record of a ``std_msgs/String`` ``data`` (JSON)."""
    return json.loads(text)


def setup_record(run_id, model, train, speeds_kmh, speeds_m_s, train_length_m, axle_offsets_m, axle_loads_n,
                 wheel_mass_kg, phase=""):
    """``/adm/run/setup`` (train -> bridge): the run the train node asks for, with its ``phase``
    (:data:`PHASES`; empty: the bridge names it by the request, :func:`plain_run_phase`).

    Arrays (``(n_lanes,)`` speeds, ``(n_axles,)`` offsets in m, loads in N, wheelset masses in kg,
    ``None`` for the MLM) are sent as lists.
    """
    return {"run_id": run_id, "model": model, "train": train, "speeds_kmh": _list(speeds_kmh),
            "speeds_m_s": _list(speeds_m_s), "train_length_m": train_length_m,
            "axle_offsets_m": _list(axle_offsets_m), "axle_loads_n": _list(axle_loads_n),
            "wheel_mass_kg": None if wheel_mass_kg is None else _list(wheel_mass_kg), "phase": phase}


def ready_record(run_id, ds_m, n_steps, span_m, n_lanes, t0_s):
    """``/adm/run/ready`` (bridge -> train): the grid of an accepted run."""
    return {"run_id": run_id, "ds_m": ds_m, "n_steps": n_steps, "span_m": span_m, "n_lanes": n_lanes, "t0_s": t0_s}


def ready_error(run_id, message):
    """``/adm/run/ready`` (bridge -> train) of a rejected run; :func:`is_rejected` tells it apart."""
    return {"run_id": run_id, "error": message}


def is_rejected(ready: dict) -> bool:
    return "error" in ready


def status_record(node, run_id, state, **extra):
    """``/adm/run/status``: ``node`` (``bridge`` / ``train``), ``run_id``, ``state`` (:data:`RUN_STATES`).

    The bridge's ``started`` adds ``model, n_steps, n_lanes, ds_m, bridge, train`` and the
    monitoring of the run (``t0_s, monitor_lane, monitor_speed_kmh, clock_speed_kmh,
    monitor_every_steps, beam_every_steps``); its ``done`` / ``failed`` repeat all of that (a client
    that subscribed after ``started`` can still place the run's samples) and add ``wall_s, t1_s,
    message, samples``; a ``failed`` of a node carries the ``message``.
    """
    return {"node": node, "run_id": run_id, "state": state, **extra}


#: Keys of the per-passage summary (``/adm/run/summary``, ``diagnostic_msgs/DiagnosticStatus``
#: values, in this order; docs/ros.md, section "Topics", defines each), then ``samples/<topic>``.
SUMMARY_KEYS = ("run_id", "phase", "bridge", "train", "model", "speed_kmh", "peak_acc_m_s2", "t_peak_s",
                "run_time_peak_s", "step_peak", "x_front_peak_m", "limit_m_s2", "track_type", "level",
                "max_acc_all_lanes_m_s2", "speed_at_max_kmh", "n_lanes", "n_steps", "steps_done", "t0_s", "t1_s",
                "frame_id")


def summary_values(samples, **values):
    """The ``(key, text)`` pairs of a per-passage summary: :data:`SUMMARY_KEYS` in order (floats
    as ``repr``, exact), then ``samples/<topic>`` per :data:`SAMPLE_TOPICS`."""
    out = {}
    for k in SUMMARY_KEYS:
        v = values[k]
        out[k] = repr(float(v)) if isinstance(v, float) else str(v)
    for t in SAMPLE_TOPICS:
        out[f"samples{t}"] = str(int(samples.get(t, 0)))
    return out


def summary_from_values(pairs) -> dict:
    """A summary's ``{key: value}`` back from its ``(key, text)`` pairs (numbers parsed; the sample
    counts as ``samples: {topic: n}``)."""
    out: dict = {"samples": {}}
    for k, v in pairs:
        if k.startswith("samples/"):
            out["samples"][k[len("samples"):]] = int(v)
            continue
        try:
            out[k] = int(v) if v.lstrip("-").isdigit() else float(v)
        except ValueError:
            out[k] = v
    return out


def ack_record(node, run_id, received, topics=None):
    """``/adm/run/ack`` (recorder or opted-in client -> bridge): node ``node`` has received (a
    recorder: written) ``received`` messages of the current run (``run_id`` once it knows it, else
    ``None``) on ``topics`` (``None``: every one of :data:`SAMPLE_TOPICS`; a client counts the
    topics it reads, e.g. ``[TOPIC_ACCEL]``, default-namespace names)."""
    rec = {"node": node, "run_id": run_id, "received": int(received)}
    if topics is not None:
        rec["topics"] = list(topics)
    return rec


class AckCounter:
    """When a client that opted into the flow control acknowledges (no ROS; the node side is
    :class:`adm_sim.nodes.common.FlowClient`).

    The client counts the messages of the current run it receives on ``topics`` (a subset of
    :data:`SAMPLE_TOPICS`) and acknowledges its first one (so the bridge learns the topics early),
    then every :data:`ACK_EVERY`, and when it has them all: the run's final ``/adm/progress``
    record (:meth:`final`) says how many the bridge published. Each call returns the
    :func:`ack_record` to publish, or ``None``.

    Parameters
    ----------
    node : str
        The client's fully qualified node name (the bridge keys its acknowledgements by it).
    topics : sequence of str
        The counted topics (default-namespace names, :data:`SAMPLE_TOPICS`).
    """

    def __init__(self, node, topics=(TOPIC_ACCEL,)):
        unknown = [t for t in topics if t not in SAMPLE_TOPICS]
        if unknown or not topics:
            raise ValueError(f"topics: {unknown or list(topics)!r}: allowed a non-empty subset of {list(SAMPLE_TOPICS)}")
        self.node, self.topics = node, tuple(topics)
        self.received = self.acked = 0
        self.expected = None  # (run_id, messages on ``topics``) from the run's final progress record
        self.runs = {}        # run_id -> (received, published) of the runs ended, on ``topics``

    def count(self, n=1):
        """``n`` messages of ``topics`` received."""
        self.received += n
        return self._ack()

    def final(self, record):
        """A progress record (``/adm/progress``, decoded); the run's final one carries its counts."""
        if record.get("final") and isinstance(record.get("samples"), dict):
            self.expected = (record.get("run_id"), sum(int(record["samples"].get(t, 0)) for t in self.topics))
            return self._ack()
        return None

    def started(self, run_id):
        """The bridge's ``started`` of run ``run_id``: a run before it that never came whole (the
        client lost messages; the bridge stopped waiting for it) is booked with what came."""
        if self.expected is not None and self.expected[0] != run_id:
            self.runs[self.expected[0]] = (self.received, self.expected[1])
            self.received = self.acked = 0
            self.expected = None

    def _ack(self):
        whole = self.expected is not None and self.received >= self.expected[1]
        if not (whole or self.acked == 0 or self.received - self.acked >= ACK_EVERY):
            return None
        rid = None if self.expected is None else self.expected[0]
        rec = ack_record(self.node, rid, self.received, self.topics)
        self.acked = self.received
        if whole:  # the run is whole: count the next one from 0
            self.runs[rid] = (self.received, self.expected[1])
            self.received = self.acked = 0
            self.expected = None
        return rec


def request_record(node, run_id, model, phase, label):
    """``/adm/run/status`` ``requested`` (driver): run ``run_id`` (``model``) was asked for as part of
    ``phase`` (:data:`PHASES`), shown as ``label``. Published by the driver as soon as the train node
    accepted the run, so the phase is in the recording with the run id."""
    return status_record(node, run_id, REQUESTED, model=model, phase=phase, label=label)


def is_request(st: dict) -> bool:
    """Whether ``st`` is a driver's ``requested`` record of a run (it carries the run's phase)."""
    return st.get("state") == REQUESTED and st.get("run_id") is not None


def is_failure(st: dict, run_id=None) -> bool:
    """Whether the status record ``st`` reports a failure (of run ``run_id`` if given)."""
    return st.get("state") == FAILED and (run_id is None or st.get("run_id") == run_id)


def is_bridge_start(st: dict) -> bool:
    """Whether ``st`` is the bridge's ``started`` record of a run (it announces the run's timing)."""
    return st.get("node") == BRIDGE_NODE and st.get("state") == STARTED and st.get("run_id") is not None


def progress_record(run_id, model, step, n_steps, sim_time_s, samples=None):
    """``/adm/progress``: steps done of ``n_steps`` and the sim time reached (s); the run's last
    one carries ``final`` and ``samples``, the messages of each of :data:`SAMPLE_TOPICS` the run
    published (itself included)."""
    rec = {"run_id": run_id, "model": model, "step": step, "n_steps": n_steps, "sim_time_s": sim_time_s}
    if samples is not None:
        rec.update(final=True, samples=dict(samples))
    return rec


def bridge_description_record(bridge, description, n0_hz, step, delta_zeta, delta_zeta_lanes, track_type,
                              acc_limit_m_s2, supports_m=(), frequencies_hz=(), modal_masses_kg=(), response_m=0.0,
                              midspan_m=None):
    """``/adm/bridge/description`` (latched): ``bridge`` the exact fields of :class:`adm_sim.model.bridge.Bridge`
    (:func:`bridge_fields` of it rebuilds it: ``Bridge(**bridge_fields(record["bridge"]))``; a continuous
    deck's ``spans_m``, ``span_EJ_Nm2``, ``span_mu_kg_m`` are lists, empty for one span), ``description``
    its one-line text, ``n0_hz``, the support abscissae ``supports_m`` (m from the left abutment, both
    abutments and every pier), the natural frequencies ``frequencies_hz`` and modal masses
    ``modal_masses_kg`` of the retained modes, the bridge node's ``response_m`` (where the midspan topics
    and a run's maxima are taken, m from the left abutment; 0: at ``midspan_m``, the middle of one span
    or of a deck's longest span), ``step`` the step settings (``steps_per_period,
    free_vibration_periods, ds_m``), the Δζ parameters (fraction; ``delta_zeta_lanes`` a comma
    list), the track type and its limit (m/s²)."""
    return {"bridge": bridge, "description": description, "n0_hz": n0_hz, "supports_m": _list(supports_m),
            "frequencies_hz": _list(frequencies_hz), "modal_masses_kg": _list(modal_masses_kg),
            "response_m": response_m, "midspan_m": midspan_m, "step": step,
            "delta_zeta": delta_zeta, "delta_zeta_lanes": delta_zeta_lanes, "track_type": track_type,
            "acc_limit_m_s2": acc_limit_m_s2}


def bridge_fields(bridge):
    """The keyword arguments of ``Bridge`` from the ``bridge`` of a bridge description record (its
    per-span lists as tuples, as the frozen dataclass holds them)."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in bridge.items()}


def train_description_record(train, name, description, length_m, n_axles, model, speeds_kmh):
    """``/adm/train/description`` (latched): ``train`` as given to the node (a name or a TOML file,
    ``load_train(record["train"])`` loads it), its ``name``, text, length (m), axles, the model and
    the speeds parameter (text)."""
    return {"train": train, "name": name, "description": description, "length_m": length_m, "n_axles": n_axles,
            "model": model, "speeds_kmh": speeds_kmh}


def _list(a):
    return np.asarray(a).tolist() if isinstance(a, np.ndarray) else list(a)


# ---------------------------------------------------------------------- driver lines
#: A driver's progress line on stdout: ``@<kind> <JSON>`` (kinds ``run``, ``progress``,
#: ``iteration``, ``calibration``, ``result``), read by the launch scripts.
LINE_MARK = "@"


def driver_line(kind: str, payload: dict) -> str:
    """One progress line ``@kind {json}`` (no newline)."""
    return f"{LINE_MARK}{kind} {json.dumps(payload)}"


def parse_driver_line(line: str):
    """``(kind, payload)`` of a progress line, ``(None, line)`` for any other output line."""
    if not line.startswith(LINE_MARK):
        return None, line
    kind, _, payload = line[len(LINE_MARK):].partition(" ")
    return kind, json.loads(payload)


# ---------------------------------------------------------------------- run phases
#: Phases of the Section 4 calibration a run can belong to.
PHASE_DIM = "dim"                  # DIM sweep (target curve, refinement)
PHASE_MLM_ZETA = "mlm_zeta"        # MLM over the full range, Δζ = 0
PHASE_MLM_ZETA_DZ = "mlm_zeta_dz"  # MLM over the full range, one Δζ (the adapted curve)
PHASE_BRACKETING = "bracketing"    # MLM lanes carrying several Δζ: the bracketing ladder
PHASE_ROOT_SEARCH = "root_search"  # MLM, one Δζ on fewer lanes than the full range
PHASES = (PHASE_DIM, PHASE_MLM_ZETA, PHASE_MLM_ZETA_DZ, PHASE_BRACKETING, PHASE_ROOT_SEARCH)
#: The phase of a run in a recording made before runs carried their phase (replay).
PHASE_UNKNOWN = "unknown"
#: The one table of the phases' names: run phase -> (its series in the viewer, its ``@run`` label).
PHASE_NAMES = {PHASE_DIM: ("DIM", "DIM"), PHASE_MLM_ZETA: ("MLM ζ", "MLM zeta"),
               PHASE_MLM_ZETA_DZ: ("MLM ζ+Δζ", "MLM zeta+dz"), PHASE_BRACKETING: ("bracketing", "MLM trial"),
               PHASE_ROOT_SEARCH: ("root search", "MLM trial"), PHASE_UNKNOWN: ("phase unknown", None)}
#: The phase a calibration request carries -> the run phase above (``adm_calib.lanes.PHASES`` are its keys,
#: in the order a calibration runs them).
#: The calibration names its phase with every lane request; the calibration node maps it here and
#: hands it on with the run (:func:`request_record`).
CALIBRATION_PHASES = {"mlm": PHASE_MLM_ZETA, "mlm_refine": PHASE_ROOT_SEARCH, "dim": PHASE_DIM,
                      "dim_refine": PHASE_DIM, "dim_peak_refine": PHASE_DIM, "ladder": PHASE_BRACKETING,
                      "root": PHASE_ROOT_SEARCH, "check": PHASE_ROOT_SEARCH, "adapted": PHASE_MLM_ZETA_DZ}


def plain_run_phase(model: str, delta_zeta: float, delta_zeta_lanes) -> str:
    """The phase of a run requested outside a calibration (a crossing, a sweep), named by its request.

    Parameters
    ----------
    model : str
        ``dim`` or ``mlm`` (the train node's ``model``).
    delta_zeta : float
        The bridge node's ``delta_zeta`` (fraction).
    delta_zeta_lanes : str or sequence of float
        The bridge node's ``delta_zeta_lanes`` (a comma list, empty: every lane ``delta_zeta``).

    Returns
    -------
    str
        :data:`PHASE_DIM`; :data:`PHASE_BRACKETING` (several Δζ over the lanes, drawn one curve per
        Δζ); :data:`PHASE_MLM_ZETA` (Δζ = 0) or :data:`PHASE_MLM_ZETA_DZ` (one Δζ).
    """
    if model.lower() == "dim":
        return PHASE_DIM
    if isinstance(delta_zeta_lanes, str):
        lanes = [float(x) for x in delta_zeta_lanes.split(",") if x.strip()]
    else:
        lanes = [float(x) for x in delta_zeta_lanes]
    dz = set(lanes) if lanes else {float(delta_zeta)}
    if len(dz) > 1:
        return PHASE_BRACKETING
    return PHASE_MLM_ZETA if dz == {0.0} else PHASE_MLM_ZETA_DZ


# ---------------------------------------------------------------------- rerun
#: Session sim time (s), continuous over the runs of one session (``/clock``).
SIM_TIME = "sim_time"
#: Time since the first axle entered the bridge in the monitored lane (s); 0 at every run start.
RUN_TIME = "run_time"
#: Train speed (sequence, km/h rounded to 1 km/h).
SPEED = "speed_kmh"
#: Calibration step (sequence).
ITERATION = "iteration"
TIMELINES = (SIM_TIME, RUN_TIME, SPEED, ITERATION)

#: Entity roots of an adm-sim recording (the blueprint's view origins); the logger writes below them.
ENTITIES = {
    "acceleration": "runs/acceleration",      # runs/acceleration/run_NN: Scalars
    "beam": "runs/beam",                      # runs/beam/run_NN/{deflection,axles,peak_*}, runs/beam/{supports,axis}
    "run_info": "runs/info",                  # TextDocument (markdown table)
    "sweep_main": "sweep/curves",             # sweep/curves/{DIM, MLM_zeta, MLM_zeta_dz, unknown, ...}
    "sweep_trials": "sweep/trials",           # sweep/trials/{bracketing,root_search}/NN
    "dz": "calibration/delta_zeta_pct",       # .../{bracketing,root_search}
    "peaks": "calibration/peak_m_s2",         # .../{mlm_bracketing,mlm_root_search,dim}
    "cal_result": "calibration/result",       # TextDocument
    # outside the default views (replay.py): generic topics, diagnostics, MCAP metadata
    "topics": "topics",
    "diagnostics": "diagnostics",
    "metadata": "metadata",
}


#: Speed-sweep curve (:func:`sweep_curve_path`) of a run of each phase that is drawn as one curve;
#: the runs of :data:`TRIAL_PHASES` are drawn one curve per Δζ (:func:`sweep_trial_path`).
SWEEP_CURVE_NAMES = {PHASE_DIM: "DIM", PHASE_MLM_ZETA: "MLM_zeta", PHASE_MLM_ZETA_DZ: "MLM_zeta_dz",
                     PHASE_UNKNOWN: PHASE_UNKNOWN}
#: Phases whose runs are damping trials (Δζ per iteration: :func:`delta_zeta_path`).
TRIAL_PHASES = (PHASE_BRACKETING, PHASE_ROOT_SEARCH)


def run_tag(run_id: int) -> str:
    """Entity path part of a run: ``run_NN``."""
    return f"run_{int(run_id):02d}"


def acceleration_path(run_id: int) -> str:
    """Midspan acceleration of run ``run_id`` (Scalars)."""
    return f"{ENTITIES['acceleration']}/{run_tag(run_id)}"


def beam_path(run_id: int | None = None, part: str | None = None) -> str:
    """Beam view entity: the root, a run's (``run_NN``) or one of its parts (``deflection``,
    ``axles``, ``peak_shape``, ``peak_axles``); with ``run_id`` None, a static part of the
    view (``supports``, ``axis``)."""
    path = ENTITIES["beam"] if run_id is None else f"{ENTITIES['beam']}/{run_tag(run_id)}"
    return path if part is None else f"{path}/{part}"


def sweep_curve_path(name: str, trials: bool = False) -> str:
    """A speed-sweep curve (``DIM``, ``MLM_zeta``, ...) in the main or the trials view."""
    return f"{ENTITIES['sweep_trials' if trials else 'sweep_main']}/{name}"


def sweep_trial_path(phase: str, n: int) -> str:
    """Damping trial ``n`` (1, 2, ...) of a calibration phase (bracketing / root search)."""
    return f"{ENTITIES['sweep_trials']}/{phase}/{int(n):02d}"


def delta_zeta_path(phase: str) -> str:
    """Δζ per iteration of a calibration phase."""
    return f"{ENTITIES['dz']}/{phase}"


def peak_path(series: str) -> str:
    """Peak per iteration: ``mlm_<phase>`` or ``dim``."""
    return f"{ENTITIES['peaks']}/{series}"


def is_entity(path: str) -> bool:
    """Whether ``path`` is one of :data:`ENTITIES` or lies below one."""
    p = path.strip("/")
    return any(p == root or p.startswith(root + "/") for root in ENTITIES.values())


__all__ = [n for n in dir() if n.isupper() or n in (
    "relative", "check_namespace", "ack_record", "AckCounter", "summary_values", "summary_from_values", "encode", "decode", "setup_record", "ready_record", "ready_error", "is_rejected", "status_record",
    "is_failure", "is_bridge_start", "progress_record", "bridge_description_record", "bridge_fields",
    "train_description_record",
    "driver_line", "parse_driver_line", "request_record", "is_request", "plain_run_phase", "run_tag", "acceleration_path",
    "beam_path", "sweep_curve_path", "sweep_trial_path", "delta_zeta_path", "peak_path", "is_entity")]
