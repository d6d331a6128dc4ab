"""Run driver node: requests runs of the bridge/train pair and has them recorded.

:class:`RunDriver` is the run client of the node graph. From a worker thread (never inside a
callback) :meth:`RunDriver.request_run` sets parameters on the bridge and train nodes through their
parameter services (the run's phase among them), calls ``/train/start_run`` and blocks until
``/adm/run/result`` arrives; the executor keeps spinning in the main thread. The recording side,
:class:`adm_sim.nodes.recorder.RunRecorder`, writes every monitoring topic to an MCAP file
(``record_path``), acknowledges what it wrote (the bridge's flow control) and checks every run's
sample counts; the driver feeds the messages to its rerun logger
(:class:`adm_sim.recording.rerun_log.RunLogger`: ``rrd_path``, ``rerun_spawn``, ``rerun_connect``;
the recording carries the default blueprint).

``python -m adm_sim.nodes.driver --ros-args -p summary_path:=run.json`` runs one crossing or sweep
with the train node's current parameters (``launch_scripts/crossing.py`` starts it).
"""

from __future__ import annotations

import json
import sys
import threading
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import AccelStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import Trigger

from adm_sim import protocol as P
from adm_sim.errors import AdmSimError, InputError, PlausibilityWarning, RunError  # RunError: a run failed or its partners went away
from adm_sim.files import claim_output, release, write_atomic
from adm_sim.nodes import common as c
from adm_sim.nodes.flow_client import named_publishers
from adm_sim.nodes.params import DRIVER_SPECS
from adm_sim.nodes.recorder import RunRecorder
from adm_sim.model.plausibility import check_response


#: Topics the driver records (topic, type); its own publications are recorded as it publishes.
RECORDED = [(P.TOPIC_CLOCK, Clock), (P.TOPIC_ACCEL, AccelStamped), (P.TOPIC_STATE, Float64MultiArray),
            (P.TOPIC_BEAM, Float64MultiArray), (P.TOPIC_AXLES, Float64MultiArray), (P.TOPIC_PROGRESS, String),
            (P.TOPIC_DIAGNOSTICS, DiagnosticArray), (P.TOPIC_RESULT, Float64MultiArray), (P.TOPIC_STATUS, String),
            (P.TOPIC_SUMMARY, DiagnosticStatus), (P.TOPIC_BRIDGE_DESC, String), (P.TOPIC_TRAIN_DESC, String)]

#: The topics of :data:`RECORDED`.
RECORDED_TOPICS = frozenset(topic for topic, _type in RECORDED)

#: ``/diagnostics`` status name of the plausibility warnings of a run's result (:meth:`RunDriver.warn_implausible`).
DIAG_PLAUSIBILITY = "adm_sim/driver: plausibility of the result"


#: The driver's output parameters and the suffix each must have (:func:`adm_sim.files.claim_output`).
OUTPUT_PARAMS = (("record_path", ".mcap"), ("rrd_path", ".rrd"), ("summary_path", ".json"))


def claim_outputs(values):
    """Check and claim the output files named by the parameters ``values`` at start-up, before
    anything is created: the one rule of :mod:`adm_sim.files` (regular file, writable folder, not
    replaced unless ``overwrite``, two outputs never the same file, a second writer refused).
    Returns ``{param: Path}`` of the non-empty ones; raises :class:`InputError`."""

    out = {}
    try:
        for name, suffix in OUTPUT_PARAMS:
            text = values.get(name, "")
            if not text:
                continue
            same = [n for n, p in out.items() if p.resolve() == Path(text).resolve()]
            if same:
                raise InputError(f"{name}: {text!r} is the {same[0]} file; give different files")
            out[name] = claim_output(text, name, bool(values.get("overwrite")), suffix,
                                     overwrite_hint="set -p overwrite:=true to replace it")
    except InputError:
        for path in out.values():  # nothing claimed is kept (its lock file is removed)
            release(path)
        raise
    return out


_SAY_LOCK = threading.Lock()
#: Set True to silence the ``@kind`` progress lines (benchmarks, tests).
QUIET = False


def say(kind, **payload):
    """One machine-readable progress line on stdout (``@kind {json}``) for launch scripts."""
    if QUIET:
        return
    line = P.driver_line(kind, payload) + "\n"
    with _SAY_LOCK:
        sys.stdout.write(line)
        sys.stdout.flush()


class RunDriver(c.NodeBase):
    """Requests runs and records them; see the module docstring."""

    #: Parameters the job reads once, when it starts: a set while the job runs is refused (it
    #: would change nothing), with the reason (:meth:`lock_reason`).
    job_parameters = ()

    def __init__(self, name=P.DRIVER_NODE, extra_specs=(), **kw):
        super().__init__(name, **kw)
        self.job_started = False
        self.declare_specs(list(DRIVER_SPECS) + list(extra_specs), on_set=self._check_set)
        p = self.param_values()
        self.outputs = claim_outputs(p)  # before any file is created (exit 2, one line)
        self.finished = False
        self.error = None
        self.run = None  # the driver has no lockstep exchange of its own
        self._lock = threading.Lock()
        self._result = None
        self._status = {}
        self._event = threading.Event()
        self._clock_ns = 0
        self._desc = {}
        self._current = None  # (run_id, model, lane label)
        #: CDR bytes of this node's own publications on the topics it records, each written as it was
        #: published (:meth:`publish_recorded`) and not yet seen back on the node's own subscription
        self._own = Counter()
        self._own_lock = threading.Lock()
        self.n_runs = 0
        self._run_ids = []  # the runs requested, in order
        self._last_rx = time.monotonic()
        #: the recording side (MCAP, rerun, acknowledgements, per-run counts)
        self.rec = RunRecorder(self, self.outputs, chunk_size=p["chunk_size"], rerun_spawn=p["rerun_spawn"],
                               rerun_connect=p["rerun_connect"])
        self.recorder = self.rec.mcap  # McapRecorder (or None)
        for topic, typ in RECORDED:
            qos = c.QOS_LATCHED if topic.endswith("description") else (
                c.QOS_CONTROL if topic in (P.TOPIC_RESULT, P.TOPIC_STATUS, P.TOPIC_SUMMARY)
                else c.QOS_MONITOR)  # every counted topic (/diagnostics included) at least the flow window deep
            # taken serialised: the MCAP file gets the bytes as they came, the rest the message
            self.create_subscription(typ, P.relative(topic), self._make_cb(topic, typ), qos, raw=True)
        #: the driver's ``requested`` records (the run id with its phase), recorded as published
        self.pub_request = self.create_publisher(String, P.relative(P.TOPIC_STATUS), c.QOS_CONTROL)
        #: the plausibility verdict of a run's result (:meth:`warn_implausible`)
        self.pub_plausibility = self.create_publisher(DiagnosticArray, P.relative(P.TOPIC_DIAGNOSTICS), c.QOS_CONTROL)
        self.last_phase = None  # phase of the last run requested (the iterations that follow it)
        self.cli_start = self.create_client(Trigger, P.relative(P.SERVICE_START_RUN))
        self.params = {n: AsyncParameterClient(self, n) for n in (P.BRIDGE_NODE, P.TRAIN_NODE)}

    # ------------------------------------------------------------------ parameters
    def lock_reason(self):
        """Why the :attr:`job_parameters` are locked now: the job in progress (and its run)."""
        run = "" if self._current is None else f"run {self._current[0]} of "
        return f"{run}its job is in progress ({', '.join(self.job_parameters)}: read once, when it started)"

    def _check_set(self, params):
        """On-set (after the ranges): refuse a set of a :attr:`job_parameters` while the job runs."""
        if self.job_started and not self.finished and any(p.name in self.job_parameters for p in params):
            return SetParametersResult(successful=False, reason=(
                f"{self.get_name()}: parameters are locked while {self.lock_reason()}"))
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ subscriptions
    def _make_cb(self, topic, msg_type):
        """Subscription callback of ``topic`` (messages of ``msg_type`` taken serialised): record the
        message (its bytes to MCAP, the message to the viewer, :meth:`RunRecorder.write`), then keep
        what the driver itself needs of it."""
        own = {P.TOPIC_RESULT: self._take_result, P.TOPIC_STATUS: self._take_status,
               P.TOPIC_BRIDGE_DESC: lambda msg: self._desc.__setitem__("bridge", json.loads(msg.data)),
               P.TOPIC_TRAIN_DESC: lambda msg: self._desc.__setitem__("train", json.loads(msg.data)),
               P.TOPIC_PROGRESS: self._say_progress}.get(topic)
        counted = topic in P.SAMPLE_TOPICS

        def cb(data):
            self._last_rx = time.monotonic()
            msg = deserialize_message(data, msg_type)
            if isinstance(msg, Clock):
                self._clock_ns = self.rec.clock_ns = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
            try:
                if not self._own_echo(data):  # this node's own message is written once, as published
                    self.rec.write(topic, msg, self.rec.log_time_ns(msg), serialized=data)
            except RunError as exc:  # a refused write (full disk, ulimit -f): the run's failure
                self.recorder_failed(exc)
                return
            if own is not None:
                own(msg)
            if counted:
                self.rec.count(topic, msg, self._current[0] if self._current else None)

        return cb

    def publish_recorded(self, pub, topic, msg):
        """Record one of the driver's own messages at the current sim time, then publish it.

        It is written here, not when the node's own subscription of ``topic`` (if it records that
        topic) hands it back: the recording does not depend on that echo, which can come after the
        run's result or, under load, not before the file is closed; the echo is not written a second
        time (:meth:`_own_echo`). The bytes published are the bytes recorded."""
        data = serialize_message(msg)
        if topic in RECORDED_TOPICS:
            with self._own_lock:
                self._own[data] += 1
        try:
            self.rec.write(topic, msg, self._clock_ns, serialized=data)
        except RunError as exc:
            raise self._named(exc) from None
        pub.publish(data)

    def _own_echo(self, data):
        """Whether ``data`` (a message taken by a recording subscription) is one of this node's own
        publications, written already by :meth:`publish_recorded` (each is matched once)."""
        if not self._own:
            return False
        with self._own_lock:
            if self._own[data] <= 0:
                return False
            self._own[data] -= 1
            if not self._own[data]:
                del self._own[data]
            return True

    def _named(self, exc):
        """``exc`` (a recorder's failure) as the failure of the run it hit: the current run, else
        the runs recorded so far."""
        if str(exc).startswith("run"):
            return exc
        if self._current is not None:
            return RunError(f"run {self._current[0]}: {exc}")
        ids = self._run_ids
        which = "" if not ids else f"run {ids[0]}: " if len(ids) == 1 else f"runs {ids[0]}-{ids[-1]}: "
        return RunError(f"{which}{exc}")

    def recorder_failed(self, exc):
        """A write the recorder could not make (MCAP or rerun: a full disk, ``ulimit -f``) fails the
        run it belongs to and ends the node's job: exit 1, one line naming the run."""
        if self.error is None:
            self.error = self._named(exc)
        self.finished = True

    def _take_result(self, msg):
        with self._lock:
            self._result = c.matrix_from_msg(msg)
        self._event.set()

    def _take_status(self, msg):
        st = json.loads(msg.data)
        with self._lock:
            self._status[(st.get("node"), st.get("run_id"))] = st
        if P.is_failure(st):
            self._event.set()

    def _say_progress(self, msg):
        pr = json.loads(msg.data)
        if self._current is not None and pr.get("run_id") == self._current[0]:  # not a late tick of a finished run
            say("progress", **pr)

    # ------------------------------------------------------------------ descriptions
    def description(self, which, timeout_s=10.0):
        """Latched description of the bridge or train node (JSON dict)."""
        t_end = time.monotonic() + timeout_s
        while which not in self._desc:
            if time.monotonic() > t_end:
                raise RunError(f"no {which} description on {P.DESCRIPTION_TOPICS[which]} after {timeout_s:g} s: "
                               f"is the {which} node running?")
            self._event.wait(0.05)
        return self._desc[which]

    # ------------------------------------------------------------------ blocking calls (worker thread)
    def _wait_future(self, fut, what, timeout_s=120.0):
        """Wait for a service answer. A node that left the graph fails at once (checked every
        second); one that is alive but busy (a first run compiles kernels, a loaded machine) is
        given ``timeout_s``."""
        done = threading.Event()
        fut.add_done_callback(lambda _f: done.set())
        t_end = time.monotonic() + timeout_s
        while not done.wait(min(1.0, max(0.0, t_end - time.monotonic()))):
            if time.monotonic() >= t_end:
                raise RunError(f"{what}: no answer after {timeout_s:g} s")
            self._check_alive()
        return fut.result()

    def set_params(self, node_name, **values):
        """Set parameters on ``bridge`` or ``train``; raises :class:`InputError` with the node's reason."""
        if not values:
            return
        cli = self.params[node_name]
        if not cli.wait_for_services(timeout_sec=10.0):
            raise RunError(f"parameter services of node '{node_name}' not available")
        plist = [Parameter(k, value=v) for k, v in values.items()]
        res = self._wait_future(cli.set_parameters(plist), f"set parameters on '{node_name}'")
        for _p, r in zip(plist, res.results):
            if not r.successful:
                raise InputError(f"{node_name}: {r.reason}")

    def wait_for_graph(self, timeout_s=30.0):
        """Block until both nodes, their services and the result topic are there, then until
        ``wait_clients`` clients opted into the flow control (:meth:`wait_for_clients`)."""
        t_end = time.monotonic() + timeout_s
        while not (self.cli_start.service_is_ready() and self.count_publishers(P.relative(P.TOPIC_RESULT)) > 0):
            if time.monotonic() > t_end:
                raise RunError(f"bridge/train nodes not found after {timeout_s:g} s")
            self._event.wait(0.05)
        self.wait_for_clients()

    def opted_in_clients(self):
        """Fully qualified names of the other nodes that publish ``/adm/run/ack`` (the clients that
        opted into the flow control, other recorders)."""
        me = self.get_fully_qualified_name()
        infos = self.get_publishers_info_by_topic(self.resolve_topic_name(P.relative(P.TOPIC_ACK)))
        return [n for n in named_publishers(infos) if n != me]  # a node not yet known by name is not counted

    def wait_for_clients(self):
        """Block until ``wait_clients`` other nodes publish ``/adm/run/ack`` (at most
        ``run_timeout_s``; then :class:`RunError`), so that they are waited for from the first run."""
        want = int(self.get_parameter("wait_clients").value)
        if want <= 0:
            return
        print(f"waiting for {want} client(s) to opt into the flow control (publishers of "
              f"{self.resolve_topic_name(P.relative(P.TOPIC_ACK))})", flush=True)
        timeout_s = float(self.get_parameter("run_timeout_s").value)
        t_end = time.monotonic() + timeout_s
        while len(self.opted_in_clients()) < want:
            if time.monotonic() > t_end:
                raise RunError(f"wait_clients: {want} client(s) asked for, {len(self.opted_in_clients())} opted in "
                               f"within run_timeout_s = {timeout_s:g} s")
            self._event.wait(0.05)
        # the bridge takes them at the run's set-up from its own view of the graph, which can lag
        # this node's by a second or more on a loaded machine (one it misses then joins at its first
        # acknowledgement of the run, FlowControl.join; the wait keeps that the exception)
        self._event.wait(2.0)
        print(f"clients opted in: {', '.join(self.opted_in_clients())}", flush=True)

    def _check_alive(self):
        ns = self.get_namespace()
        names = {n for n, n_ns in self.get_node_names_and_namespaces() if n_ns == ns}
        missing = [n for n in (P.BRIDGE_NODE, P.TRAIN_NODE) if n not in names]
        if not missing:
            return
        run = self._current[0] if self._current else None
        # a node that stopped because its partner died says so on /adm/run/status before it goes
        t_end = time.monotonic() + 1.0
        while True:
            failed = self._failures(run)
            if failed or time.monotonic() > t_end:
                break
            self._event.wait(0.05)
        which = " and ".join(f"'{n}'" for n in missing)
        why = f" ({failed[0]['node']}: {failed[0].get('message', '')})" if failed else ""
        raise RunError(f"node {which} vanished during run {'?' if run is None else run}{why}")

    def _failures(self, run_id):
        """The ``failed`` status records of run ``run_id`` received so far (one per node)."""
        with self._lock:
            return [s for s in self._status.values() if P.is_failure(s, run_id)]

    def _wait_run_ended(self, run_id, timeout_s=5.0):
        """After one node reported run ``run_id`` failed, wait (at most ``timeout_s``) until the other
        has ended it too (the train node answers the bridge's failure with its own), so that the
        next request does not find the other node's parameters still locked by the failed run."""
        t_end = time.monotonic() + timeout_s
        while time.monotonic() < t_end:
            if {P.BRIDGE_NODE, P.TRAIN_NODE} <= {s.get("node") for s in self._failures(run_id)}:
                return
            time.sleep(0.05)

    def request_run(self, model=None, speeds_kmh=None, delta_zeta=None, delta_zeta_lanes=None, label=None,
                    phase=None):
        """One co-simulated run; returns ``{"speeds_kmh", "max_acc_m_s2", "max_disp_m", "delta_zeta", "phase", ...}``.

        ``None`` leaves the node's current parameter; ``speeds_kmh`` may be an array (sent as an
        exact comma list), ``delta_zeta_lanes`` an array with one value per lane. ``phase``
        (:data:`adm_sim.protocol.PHASES`) is what the run is for; ``None``: a run outside a
        calibration, named by its request (:func:`adm_sim.protocol.plain_run_phase`). It is
        published with the run id (``/adm/run/status`` ``requested``, so recorded in the MCAP),
        printed with the ``@run`` lines and handed to the rerun logger.
        """
        if phase is not None and phase not in P.PHASES:
            raise InputError(f"phase: {phase!r} is not a run phase; allowed {', '.join(P.PHASES)}")
        phase = self._set_run_params(model=model, speeds_kmh=speeds_kmh, delta_zeta=delta_zeta,
                                     delta_zeta_lanes=delta_zeta_lanes, phase=phase)
        with self._lock:
            self._result = None
        self._event.clear()
        # the run's time counts from the request that started it: the response can come after the
        # run ended when this node's executor is behind with the monitoring it takes
        t0, info = self._start_run()
        run_id, model = int(info["run_id"]), info["model"]
        self.last_phase = phase
        lab = label or model.upper()
        self._current = (run_id, model, f"{lab} run {run_id}")
        self._run_ids.append(run_id)
        request = c.json_msg(P.request_record(self.get_name(), run_id, model, phase, lab))
        self.publish_recorded(self.pub_request, P.TOPIC_STATUS, request)
        self._take_status(request)  # kept as the subscription keeps every status record
        say("run", run_id=run_id, model=model, lanes=int(info["lanes"]), state="started", label=lab, phase=phase)
        res = self._wait_result(run_id, t0)
        wall = time.perf_counter() - t0
        if self.rec.attached:
            self.rec.check_run(run_id, phase, lambda: self._bridge_status(run_id))
        self._current = None
        self.n_runs += 1
        out = {"run_id": run_id, "model": model, "speeds_kmh": res[0], "max_acc_m_s2": res[1],
               "max_disp_m": res[2], "delta_zeta": res[3], "wall_s": wall, "phase": phase}
        if model == "dim":  # the DIM's contact check, from the bridge's done record (it follows the result)
            out["contact"] = self._bridge_contact(run_id)
        self.warn_implausible(out)
        i = int(np.argmax(res[1]))
        say("run", run_id=run_id, model=model, state="done", wall_s=round(wall, 3),
            max_acc_m_s2=float(res[1][i]), speed_kmh=float(res[0][i]), label=lab, phase=phase)
        return out

    def _set_run_params(self, *, model, speeds_kmh, delta_zeta, delta_zeta_lanes, phase):
        """Set the parameters of a run request (:meth:`request_run`) on the train and bridge nodes;
        returns the run's phase (``phase``, else the one of a plain run of those parameters)."""
        tp, bp = {}, {}
        if model is not None:
            tp["model"] = model
        if speeds_kmh is not None:
            tp["speeds_kmh"] = speeds_kmh if isinstance(speeds_kmh, str) else c.format_float_list(speeds_kmh)
        if delta_zeta is not None:
            bp["delta_zeta"] = float(delta_zeta)
        if delta_zeta_lanes is not None:
            bp["delta_zeta_lanes"] = "" if len(delta_zeta_lanes) == 0 else c.format_float_list(delta_zeta_lanes)
        if phase is None:
            desc = self.description(P.BRIDGE_NODE)
            phase = P.plain_run_phase(model or self._train_model(),
                                      desc["delta_zeta"] if delta_zeta is None else delta_zeta,
                                      desc["delta_zeta_lanes"] if delta_zeta_lanes is None else delta_zeta_lanes)
        tp["run_phase"] = phase
        self.set_params(P.TRAIN_NODE, **tp)
        self.set_params(P.BRIDGE_NODE, **bp)
        return phase

    def _start_run(self, retry_s=15.0):
        """Call ``~/start_run`` until the train node accepts (it asks to retry while the bridge is
        not connected yet, at most ``retry_s``); returns ``(time.perf_counter() of the accepted
        request, {key: value} of its answer)``."""
        t_end = time.monotonic() + retry_s
        while True:
            t0 = time.perf_counter()
            resp = self._wait_future(self.cli_start.call_async(Trigger.Request()), P.SERVICE_START_RUN)
            if resp.success:
                return t0, dict(kv.split("=", 1) for kv in resp.message.split())
            if "retry" not in resp.message or time.monotonic() > t_end:
                raise RunError(f"{P.SERVICE_START_RUN} refused: {resp.message}")
            self._event.wait(0.1)

    def _wait_result(self, run_id, t0):
        """Block until run ``run_id``'s result (rows :data:`adm_sim.protocol.RESULT_ROWS`) arrives;
        raises :class:`RunError` when a node reports it failed, a node vanishes or the run takes
        longer than ``run_timeout_s`` since ``t0`` (``time.perf_counter()``)."""
        timeout = self.get_parameter("run_timeout_s").value
        last_check = time.monotonic()
        while True:
            self._event.wait(0.2)
            with self._lock:
                res = self._result
            failed = self._failures(run_id)
            if failed:
                self._wait_run_ended(run_id)
                raise RunError(f"run {run_id} failed on node '{failed[0]['node']}': {failed[0].get('message', '')}")
            if res is not None:
                return res
            self._event.clear()
            if time.monotonic() - last_check > 1.0:
                self._check_alive()
                last_check = time.monotonic()
            if time.perf_counter() - t0 > timeout:
                raise RunError(f"run {run_id} took longer than run_timeout_s = {timeout:g} s")

    def warn_implausible(self, r):
        """The plausibility warnings of run ``r``'s result (:func:`adm_sim.model.plausibility.check_response`,
        as ``adm-sim sweep`` gives them): its largest acceleration and deflection, named by the run,
        its model and speed; once per run, each as one ``warning: <node>: ...`` line and as a WARN
        status :data:`DIAG_PLAUSIBILITY` on ``/diagnostics`` (recorded with the run)."""
        acc, disp, v = (np.asarray(r[k], dtype=float) for k in ("max_acc_m_s2", "max_disp_m", "speeds_kmh"))
        if not acc.size:
            return []
        span = float(self.description(P.BRIDGE_NODE)["bridge"]["span_m"])
        i, j = int(np.argmax(acc)), int(np.argmax(disp))
        run = f"run {r['run_id']} ({str(r['model']).upper()})"
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PlausibilityWarning)
            check_response(span, acc[i], disp[j], f"{run} at {v[i]:g} km/h", f"{run} at {v[j]:g} km/h")
        texts = [str(w.message) for w in caught if issubclass(w.category, PlausibilityWarning)]
        for text in texts:
            warnings.warn(text, PlausibilityWarning, stacklevel=2)
        if texts:
            st = [DiagnosticStatus(level=DiagnosticStatus.WARN, name=DIAG_PLAUSIBILITY, hardware_id=P.BRIDGE_NODE,
                                   message=text, values=[KeyValue(key="run_id", value=str(r["run_id"]))])
                  for text in texts]
            arr = DiagnosticArray(status=st)
            arr.header.stamp.sec, arr.header.stamp.nanosec = divmod(self._clock_ns, 1_000_000_000)
            self.publish_recorded(self.pub_plausibility, P.TOPIC_DIAGNOSTICS, arr)
        return texts

    def _bridge_contact(self, run_id, wait_s=5.0):
        """The ``contact`` of the bridge's ``done`` record of run ``run_id`` (:meth:`ContactCheck.to_dict
        <adm_sim.integrate.contact.ContactCheck.to_dict>`), waiting up to ``wait_s`` for it; a lost
        contact is warned as one line. ``None`` if the record does not come."""
        t_end = time.monotonic() + wait_s
        while True:
            st = self._bridge_status(run_id)
            if st is not None and st.get("state") == P.DONE:
                contact = st.get("contact")
                if contact and contact.get("status") == "contact_lost":
                    fl = contact["first_loss"]
                    warnings.warn(f"run {run_id} (DIM): contact lost: the wheel of axle {fl['axle']} would lift off "
                                  f"the rail at {fl['speed_kmh']:.6g} km/h, t = {fl['time_s']:.4g} s (contact force "
                                  f"{fl['force_n'] / 1e3:.4g} kN < 0)", PlausibilityWarning, stacklevel=3)
                return contact
            if time.monotonic() > t_end:
                return None
            self._event.wait(0.05)

    def _bridge_status(self, run_id):
        with self._lock:
            return self._status.get((P.BRIDGE_NODE, run_id))

    @property
    def incomplete(self):
        """Runs not recorded whole (:attr:`RunRecorder.incomplete`)."""
        return self.rec.incomplete

    def _train_model(self):
        """The train node's ``model`` (its latched description)."""
        return self.description(P.TRAIN_NODE)["model"]

    # ------------------------------------------------------------------ the driver's own job
    def job(self):
        """One run with the train node's current parameters; writes ``summary_path``."""
        self.wait_for_graph()
        r = self.request_run()
        bd = self.description("bridge")
        summary = {"run_id": r["run_id"], "model": r["model"], "bridge": bd["description"],
                   "span_m": bd["bridge"]["span_m"], "spans_m": bd["bridge"].get("spans_m", []),
                   "supports_m": bd.get("supports_m"), "frequencies_hz": bd.get("frequencies_hz"),
                   "modal_masses_kg": bd.get("modal_masses_kg"),
                   "train": self.description("train")["name"], "speeds_kmh": r["speeds_kmh"].tolist(),
                   "max_acc_m_s2": r["max_acc_m_s2"].tolist(), "max_disp_m": r["max_disp_m"].tolist(),
                   "wall_s": r["wall_s"], "phase": r["phase"], "samples": self.rec.recorded.get(r["run_id"]),
                   "incomplete_runs": self.incomplete}
        return summary

    def write_summary(self, summary):
        path = self.outputs.get("summary_path")
        if path is not None:

            write_atomic(path, lambda tmp: tmp.write_text(json.dumps(summary, indent=2)))
        say("result", **{k: v for k, v in summary.items() if k != "curves"})

    def make_executor(self):
        """rclpy's ``EventsExecutor`` (public API, in C++; as the exchange's :class:`~adm_sim.nodes.common.ExchangeLane`).

        The driver takes every monitoring message of a run (it records them) on a node with a
        dozen subscriptions, parameter services and clients: a ``SingleThreadedExecutor``
        rebuilds its wait set of all of them for every message it takes, which made the driver
        the busiest process of the main job; the events executor queues each message as it
        arrives. Callbacks and their order are those of a single-threaded executor.
        """
        return c.EventsExecutor(context=self.context)

    def begin(self):
        """Run :meth:`job` in a worker thread (the executor spins in the main thread); the node
        finishes when it returns."""
        def work():
            try:
                summary = self.job()
                if self.error is None:  # not after a recorder's failure; written by end()
                    self._summary = summary
                    self.error = self.rec.incomplete_error()  # outputs kept, exit status 1
                    self._keep_outputs = self.error is not None
            except Exception as exc:  # reported by end(); the process exits non-zero
                if self.error is None:  # the first failure is the one reported
                    self.error = self._named(exc) if isinstance(exc, RunError) and str(exc).startswith("recording") else exc
            finally:
                self.finished = True

        self.job_started = True
        threading.Thread(target=work, name="driver-job", daemon=True).start()

    def end(self, executor):
        """Drain what the nodes published last (recorder, rerun), then report the job's error."""
        t_end = time.monotonic() + 3.0
        while self.context.ok() and time.monotonic() - self._last_rx < 0.3 and time.monotonic() < t_end:
            executor.spin_once(timeout_sec=0.05)
        keep = self.error is None or getattr(self, "_keep_outputs", False)
        try:  # the outputs are closed and checked here: one that is not whole fails the run
            self.rec.finish(keep=self.finished and keep)
            if keep and getattr(self, "_summary", None) is not None:  # the summary last: the recordings are whole
                self.write_summary(self._summary)
        except RunError as exc:
            if keep:
                self.error = self._named(exc)
                self._keep_outputs = False
        if self.error is None:
            return 0
        if isinstance(self.error, AdmSimError):
            raise self.error
        raise RunError(f"{type(self.error).__name__}: {self.error}")

    def close(self):

        ok = self.finished and (self.error is None or getattr(self, "_keep_outputs", False))
        if getattr(self, "rec", None) is not None:
            try:  # after end(): nothing left to do; else (an error, an interrupt) the outputs are discarded
                self.rec.finish(keep=ok)
            except RunError:
                pass  # the job's own error is the one reported; the output was not kept
        for path in getattr(self, "outputs", {}).values():
            release(path)
        super().close()


def main(args=None):
    return c.run_node(RunDriver, args=args, name=P.DRIVER_NODE)


if __name__ == "__main__":
    sys.exit(main())
