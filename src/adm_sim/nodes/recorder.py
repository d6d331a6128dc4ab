"""The recording side of a run client: MCAP, rerun, flow-control acknowledgements, completeness.

:class:`RunRecorder` lives on a run client's node (:class:`adm_sim.nodes.driver.RunDriver`); the
node's subscriptions hand it every message. It writes them to the MCAP file (log time = the sim
time the message describes, :meth:`RunRecorder.log_time_ns`), counts the monitoring messages of
the current run and acknowledges them on ``/adm/run/ack`` (the bridge's flow control: docs/ros.md,
"Flow control"), and checks at the end of every run that it received what the bridge published
(:meth:`RunRecorder.check_run`; the counts go into the MCAP's metadata). Every message it writes
also goes to the rerun viewer through the one topic -> viewer feed that ``replay.py`` uses
(:class:`adm_sim.recording.viewer_feed.ViewerFeed`), so a live run and its replay draw alike.
"""

from __future__ import annotations

import json
import os
import threading
import time

from std_msgs.msg import String

from adm_sim import protocol as P
from adm_sim.errors import RunError
from adm_sim.nodes import common as c

#: Bridge ``/diagnostics`` statuses that belong to a run (counted with its samples).
RUN_DIAG_NAMES = (P.DIAG_NAME, P.DIAG_TRIAL_NAME)


class RunRecorder:
    """MCAP and rerun outputs of a run client, its acknowledgements and per-run sample counts.

    Parameters
    ----------
    node : rclpy.node.Node
        The client's node (the acknowledgement publisher is created on it).
    outputs : dict
        ``{"record_path" | "rrd_path": Path}`` claimed at start-up (:func:`adm_sim.nodes.driver.claim_outputs`).
    chunk_size : int
        MCAP chunk size (bytes).
    rerun_spawn, rerun_connect : bool, str
        Live rerun viewer (spawned on 127.0.0.1, or a loopback URL).
    """

    def __init__(self, node, outputs, chunk_size=65536, rerun_spawn=False, rerun_connect=""):
        self.node = node
        self.outputs = outputs
        self.lock = threading.Lock()      # the counts (executor thread and the client's worker thread)
        self.write_lock = threading.Lock()  # the MCAP writer
        self.feed_lock = threading.Lock()   # the viewer feed (subscriptions and the client's own messages)
        self.clock_ns = 0                 # the last /clock
        self._beside_files = {}
        self._finished = False
        self._direct = set()  # outputs written under their final name (new files)
        self.mcap = None
        if "record_path" in outputs:
            from adm_sim.recording.mcap_log import McapRecorder  # noqa: PLC0415  mcap only when recording

            self.mcap = McapRecorder(self._beside("record_path"), chunk_size=int(chunk_size), overwrite=True)
            # log times are sim time (the session's, from 0): the recording's real date is said here
            now_ns = time.time_ns()
            self.mcap.write_metadata("recording", {
                "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(now_ns // 1_000_000_000)),
                "started_unix_ns": now_ns, "log_time": "sim time: s of the session since its first run started",
                "header_stamps": "sim time (the monitored lane's), as log_time"})
        self.feed = None  # recording.live_viewer.LiveViewer
        if "rrd_path" in outputs or rerun_spawn or rerun_connect:
            from adm_sim.recording.live_viewer import LiveViewer  # noqa: PLC0415  rerun (~0.9 s) only with a viewer or .rrd

            self.feed = LiveViewer(save_path=self._beside("rrd_path") if "rrd_path" in outputs else None,
                                   spawn=rerun_spawn, connect_url=rerun_connect)
        self.recorded = {}    # run_id -> {topic: received} of the runs received whole
        self.incomplete = []  # runs not received whole: {"run_id", "phase", "missing": {topic: n}}
        self._reset_counts()
        self.pub_ack = None
        if self.attached:
            self.pub_ack = node.create_publisher(String, P.relative(P.TOPIC_ACK), c.QOS_CONTROL)

    @property
    def attached(self):
        """Whether anything is recorded (then the bridge waits for this recorder)."""
        return self.mcap is not None or self.feed is not None

    # ------------------------------------------------------------------ messages
    def log_time_ns(self, msg):
        """Log time of a message: its stamp; for a record without a header the sim time it
        describes (``t0_s`` of a ``started``, ``t1_s`` of a ``done``, ``sim_time_s`` of a progress
        record), else the last ``/clock`` (a run's result and summary come after its last one)."""
        stamp = getattr(getattr(msg, "header", None), "stamp", None)
        if stamp is not None:
            return stamp.sec * 1_000_000_000 + stamp.nanosec
        if isinstance(msg, String) and msg.data.startswith("{"):
            rec = json.loads(msg.data)
            st = rec.get("state")
            t = rec.get("t0_s") if st == P.STARTED else rec.get("t1_s") if st in (P.DONE, P.FAILED) else \
                rec.get("sim_time_s")
            if isinstance(t, (int, float)):
                return int(round(float(t) * 1e9))
        return self.clock_ns

    def write(self, topic, msg, t_ns, serialized=None):
        """Write one message to the MCAP file and the viewer (those there are), at log time ``t_ns``;
        ``serialized``: the message's CDR bytes as received, written to MCAP as they are."""
        if self.mcap is not None:
            with self.write_lock:
                if serialized is None:
                    self.mcap.write(topic, msg, t_ns)
                else:
                    self.mcap.write_serialized(topic, type(msg), serialized, t_ns)
        if self.feed is not None:
            with self.feed_lock:
                self.feed(topic, msg, t_ns)

    def count(self, topic, msg, run_id=None):
        """Count a monitoring message of the current run (``run_id`` if the client knows it);
        acknowledge every :data:`adm_sim.protocol.ACK_EVERY` and when the run's last one arrived."""
        if self.pub_ack is None or topic not in P.SAMPLE_TOPICS:
            return
        if topic == P.TOPIC_DIAGNOSTICS and not any(st.name in RUN_DIAG_NAMES for st in msg.status):
            return  # a calibration verdict, not a run's message
        with self.lock:
            self._rx[topic] += 1
            self._rx_total += 1
            if topic == P.TOPIC_PROGRESS:
                rec = json.loads(msg.data)
                if rec.get("final"):
                    self._expect = (rec["run_id"], rec["samples"])
            whole = self._expect is not None and all(self._rx.get(t, 0) == n for t, n in self._expect[1].items())
            if whole or self._rx_total - self._rx_acked >= P.ACK_EVERY:
                rid = self._expect[0] if self._expect else run_id
                self.pub_ack.publish(c.json_msg(P.ack_record(self.node.get_fully_qualified_name(), rid,
                                                             self._rx_total)))
                self._rx_acked = self._rx_total
            if whole:
                self.recorded[self._expect[0]] = dict(self._rx)
                self._reset_counts()

    def _reset_counts(self):
        self._rx = dict.fromkeys(P.SAMPLE_TOPICS, 0)
        self._rx_total = self._rx_acked = 0
        self._expect = None  # (run_id, {topic: published}) from the run's final progress record

    # ------------------------------------------------------------------ end of a run
    def check_run(self, run_id, phase, bridge_status, timeout_s=5.0):
        """Check that every monitoring message of run ``run_id`` was received (and recorded).

        ``bridge_status()`` returns the bridge's latest status record of the run. The bridge
        publishes ``done`` with the run's counts (``samples``) only after this recorder
        acknowledged them all, so they are normally here already; a run that is not whole
        ``timeout_s`` after its ``done`` is booked in :attr:`incomplete`. The counts go into the
        MCAP's metadata (``run_NN_samples``: ``published <topic>``, ``received <topic>``, ``whole``).
        """
        t_end = time.monotonic() + 60.0
        done_at = None
        while True:
            st = bridge_status()
            st = st if st is not None and st.get("state") in (P.DONE, P.FAILED) else None
            with self.lock:
                got = self.recorded.get(run_id)
            published = (st or {}).get("samples")
            if st is not None and done_at is None:
                done_at = time.monotonic()
            if got is not None and published is not None:
                break
            now = time.monotonic()
            if (done_at is not None and now - done_at > timeout_s) or now > t_end:
                with self.lock:
                    got = dict(self._rx)
                    self._reset_counts()
                break
            time.sleep(0.005)
        published = published or {}
        missing = {t: int(n) - int(got.get(t, 0)) for t, n in published.items() if int(n) != int(got.get(t, 0))}
        if not published:
            missing = {P.TOPIC_STATUS: 1}  # no done record: nothing tells what the run published
        if missing:
            self.incomplete.append({"run_id": run_id, "phase": phase, "missing": missing})
            self.node.get_logger().error(f"run {run_id}: recorded incomplete (missing {missing})")
        if self.mcap is not None:
            meta = {"run_id": run_id, "phase": phase, "whole": not missing}
            meta.update({f"published {t}": published.get(t, "?") for t in P.SAMPLE_TOPICS})
            meta.update({f"received {t}": got.get(t, 0) for t in P.SAMPLE_TOPICS})
            with self.write_lock:
                self.mcap.write_metadata(f"{P.run_tag(run_id)}_samples", meta)

    def incomplete_error(self):
        """The one-line error of the runs not received whole (``None`` if every run was)."""
        if not self.incomplete:
            return None
        runs = "; ".join(f"run {r['run_id']} ({r['phase']}) misses " + ", ".join(f"{n} {t}" for t, n in r["missing"].items())
                         for r in self.incomplete)
        return RunError(f"{len(self.incomplete)} run(s) not recorded whole: {runs}")

    # ------------------------------------------------------------------ files
    def _beside(self, name):
        """Where output ``name`` is written. The ``.rrd`` always goes to a temporary file beside its
        final name: rerun's file sink reports a refused write only in its log, so the recording is
        read back (:func:`adm_sim.recording.rrd_check.check_rrd`) and renamed by :meth:`finish`
        only when it is whole. The MCAP file goes to its final name when it is new (a killed
        recorder leaves a salvageable file there; a refused write removes it, see
        :class:`~adm_sim.recording.mcap_log.McapRecorder`), to a temporary file beside it when an
        earlier one is replaced (``overwrite``): the old file stays until :meth:`finish` renames
        the new one, which it does only when the job succeeded (else the temporary file is removed)."""
        path = self.outputs[name]
        if name != "rrd_path" and not path.exists():
            self._direct.add(name)
            return path
        tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}{path.suffix}")
        self._beside_files[name] = tmp
        return tmp

    def finish(self, keep):
        """Close the MCAP file and the rerun recording; rename the outputs into place only if
        ``keep`` and each was written whole (idempotent).

        Raises :class:`RunError` (one line, naming the file) when an output could not be written
        whole: the MCAP writer failed, or the ``.rrd`` does not read back. No output of the set
        is then left under its final name (temporary files and new files removed), and no earlier
        file is replaced.
        """
        if self._finished:
            return
        self._finished = True
        errors = []
        if self.mcap is not None:
            with self.write_lock:
                try:
                    self.mcap.finish()
                except RunError as exc:
                    errors.append(exc)
                    self._beside_files.pop("record_path", None)  # the writer removed its file
        if self.feed is not None:
            with self.feed_lock:
                self.feed.close()  # a viewer that stopped answering: one warning
        tmp = self._beside_files.get("rrd_path")
        if keep and tmp is not None:
            try:
                self.feed.check_file(tmp, self.outputs["rrd_path"])
            except RunError as exc:
                errors.append(exc)
                tmp.unlink(missing_ok=True)
                del self._beside_files["rrd_path"]
        for name, tmp in self._beside_files.items():  # only complete files replace the old ones
            if keep and not errors:
                os.replace(tmp, self.outputs[name])
            else:
                tmp.unlink(missing_ok=True)
        self._beside_files = {}
        if keep and errors:  # the outputs are a set: none of a run that failed to write one stays
            for name in self._direct:
                self.outputs[name].unlink(missing_ok=True)
        if errors:
            raise errors[0]
