"""Passages of a live stream of samples and run records, reported as they complete: :class:`PassageTracker`.

With run records (``/adm/run/status``) a passage is one run, its samples assigned by stamp; without
them the samples are segmented by the signal (:func:`adm_sim.monitoring.modal_passages.segment_signal`).
The rules are those of :mod:`adm_sim.monitoring.modal_id` ("Passages"); the monitor node and
``launch_scripts/monitor.py`` feed it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from adm_sim import protocol as P
from adm_sim.limits import acc_limit_m_s2
from adm_sim.monitoring.modal_passages import signal_analyses, analyse_passage, segment_signal
from adm_sim.monitoring.modal_records import IdentifySettings, Passage

__all__ = ["STAMP_TOLERANCE_S", "PassageTracker", "run_topics_for"]

#: A stamp this close below a run's ``t0_s`` belongs to that run (a stamp is ``t0`` rounded to the ns).
STAMP_TOLERANCE_S = 1e-9


@dataclass
class _Run:
    run_id: int
    t0_s: float
    scale: float = 1.0          # stamp interval -> monitored lane's time
    speed_m_s: float | None = None
    t1_s: float | None = None
    phase: str | None = None
    t: list = field(default_factory=list)
    a: list = field(default_factory=list)
    failed: str | None = None
    last_wall_s: float = 0.0
    published: int | None = None  # samples of the acceleration topic the run says it published


class PassageTracker:
    """Passages of a stream of samples and run records, reported as they complete.

    Feed it the latched descriptions (:meth:`bridge_description`, :meth:`train_description`), the
    ``/adm/run/status`` records (:meth:`status`) and the samples (:meth:`sample`, stamp in s and
    acceleration in m/s²) in any order; each completed passage is handed to ``on_passage`` and kept
    in :attr:`passages`. With run records a run's passage completes when a sample stamped at or
    after its ``t1_s`` arrives, when :meth:`poll` finds no sample for ``settle_s`` of wall time after
    its ``done``, or at :meth:`flush`. Without any run record the samples are segmented by the
    signal (:func:`segment_signal`): at :meth:`flush`, or by :meth:`poll` for a passage followed by
    ``quiet_s`` of quiet signal or of no sample at all (wall time).

    Live, records can be missed: a subscriber that matched the publisher after a run's ``started``
    places the run from its ``done`` (which repeats ``t0_s`` and the monitored lane); a ``done``
    lost with a publisher that has gone (its process ended) leaves a run open, which :meth:`poll`
    completes ``settle_s`` after its last sample once :attr:`records_expected` is False. The live
    monitor sets :attr:`records_expected` while the run-record topic has a publisher; while it is
    True, samples without a run wait for their records instead of being segmented by the signal.

    Parameters
    ----------
    track_type : str or None
        Track type of the limit (EN 1990 A2.4.4.2.1); None: the bridge description's, else ballasted.
    warn_fraction : float
        ``near`` above this fraction of the limit.
    """

    def __init__(self, *, track_type=None, warn_fraction=0.8, settings=None, on_passage=None, settle_s=1.0,
                 quiet_s=10.0, max_buffer_s=900.0):
        self.track_type, self.warn_fraction = track_type, float(warn_fraction)
        self.settings = settings or IdentifySettings()
        self.on_passage = on_passage
        self.settle_s, self.quiet_s, self.max_buffer_s = float(settle_s), float(quiet_s), float(max_buffer_s)
        self.passages: list[Passage] = []
        self.runs: list[_Run] = []
        self.phases: dict[int, str] = {}
        self.span_m: float | None = None  # the deck length (m): all spans of a continuous deck
        self.train_length_m: float | None = None
        self.bridge_track: str | None = None
        self.bridge_limit: float | None = None
        self.bridge_name: str | None = None
        self.seen_records = False
        self.loose_t: list[float] = []
        self.loose_a: list[float] = []
        self.dropped = 0  # samples outside every run (with run records)
        self.nonfinite = 0  # NaN or infinite samples received (each passage counts its own)
        self.records_expected = False  # live: a publisher of run records is on the graph
        self.last_sample_wall_s = 0.0
        self.completed: set[int] = set()  # run ids reported (a repeated done is ignored)
        self._reported_until: float | None = None  # signal passages: the last reported one's end stamp
        self._segmented_n = -1  # samples seen at the last live segmentation

    # ------------------------------------------------------------------ inputs
    def bridge_description(self, rec):
        b = rec.get("bridge") or {}
        if b.get("spans_m"):  # a continuous deck: the train leaves after its last span
            self.span_m = float(math.fsum(float(x) for x in b["spans_m"]))
        elif "span_m" in b:
            self.span_m = float(b["span_m"])
        if b.get("name"):
            self.bridge_name = str(b["name"])
        self.bridge_track = rec.get("track_type") or self.bridge_track
        if rec.get("acc_limit_m_s2") is not None:
            self.bridge_limit = float(rec["acc_limit_m_s2"])

    def train_description(self, rec):
        if rec.get("length_m") is not None:
            self.train_length_m = float(rec["length_m"])

    def status(self, rec, wall_s=0.0):
        """A ``/adm/run/status`` record (dict)."""
        state, run_id = rec.get("state"), rec.get("run_id")
        if run_id is None:
            return
        run_id = int(run_id)
        if rec.get("phase") is not None:
            self.phases[run_id] = str(rec["phase"])
        if rec.get("node") != "bridge":
            return
        if state == "started":
            self.seen_records = True
            run = _Run(run_id, float(rec.get("t0_s", 0.0)), scale=_stamp_scale(rec), last_wall_s=wall_s)
            v_kmh = rec.get("monitor_speed_kmh")
            run.speed_m_s = None if v_kmh is None else float(v_kmh) / 3.6
            self.runs.append(run)
            keep_t, keep_a = [], []
            for t, a in zip(self.loose_t, self.loose_a):  # samples that overtook their started record
                if t >= run.t0_s - STAMP_TOLERANCE_S:
                    self._put(run, t, a)
                else:
                    keep_t.append(t)
                    keep_a.append(a)
            self.loose_t, self.loose_a = keep_t, keep_a
        elif state in ("done", "failed"):
            run = self._run(run_id)
            if run is None and run_id not in self.completed and rec.get("t0_s") is not None:
                self.status({**rec, "state": "started"}, wall_s)  # its started record was missed
                run = self._run(run_id)
            if run is None:
                return
            run.last_wall_s = wall_s
            if state == "failed":
                run.failed = str(rec.get("message", "failed"))
            counts = rec.get("samples")
            if isinstance(counts, dict):  # per-topic counts of the run's done record
                n = [v for k, v in counts.items() if str(k).endswith("midspan/accel")]
                run.published = int(n[0]) if len(n) == 1 else None
            run.t1_s = float(rec["t1_s"]) if rec.get("t1_s") is not None else self._last_t1(run)
            self._rehome_beyond_end(run)

    def _rehome_beyond_end(self, run):
        """Samples that reached a run while its end was unknown but are stamped at or after it belong to
        a later run: a replay's (or a loaded graph's) sample and record publishers have no order between
        them, so the next run's samples can arrive before this run's ``done``. They are fed again (the
        first of them completes this run)."""
        raw = [run.t0_s + (s - run.t0_s) / run.scale for s in run.t]  # back to stamps (see _put)
        end = run.t1_s - STAMP_TOLERANCE_S
        cut = next((i for i, t in enumerate(raw) if t >= end), None)
        if cut is None:
            return
        moved = list(zip(raw[cut:], run.a[cut:]))
        del run.t[cut:], run.a[cut:]
        for t, a in moved:
            self.sample(t, a, run.last_wall_s)

    def sample(self, t_s, a_m_s2, wall_s=0.0):
        """One acceleration sample (stamp in s, m/s²)."""
        t, a = float(t_s), float(a_m_s2)
        self.last_sample_wall_s = wall_s
        if not math.isfinite(a):
            self.nonfinite += 1
        # [t0_s, t1_s), a stamp within 1 ns below a boundary on its later side; the latest run first, so a
        # sample of a run whose started record is in does not go to an earlier run whose done is not yet
        for run in sorted(self.runs, key=lambda r: r.t0_s, reverse=True):
            if run.t0_s - STAMP_TOLERANCE_S <= t and (run.t1_s is None or t < run.t1_s - STAMP_TOLERANCE_S):
                self._put(run, t, a)
                run.last_wall_s = wall_s
                break
        else:  # before its run's started record, or outside every run (counted when its run completes)
            self.loose_t.append(t)
            self.loose_a.append(a)
        for run in list(self.runs):  # a sample at or after a run's end completes it
            if run.t1_s is not None and t >= run.t1_s - STAMP_TOLERANCE_S:
                self._complete(run)

    def poll(self, wall_s):
        """Complete what is due by wall time (live): runs ``settle_s`` after their last input, and
        without run records a passage followed by ``quiet_s`` of quiet signal."""
        for run in list(self.runs):
            if wall_s - run.last_wall_s < self.settle_s:
                continue
            if run.t1_s is None and not self.records_expected:  # its done was lost with its publisher
                run.t1_s = self._last_t1(run)
            if run.t1_s is not None:
                self._complete(run)
        if not self.seen_records and self.loose_t and not self.records_expected:
            final = wall_s - self.last_sample_wall_s >= self.quiet_s
            n = len(self.loose_t)
            if final or n != self._segmented_n:  # nothing new: nothing to segment again
                self._segmented_n = n
                self._signal_passages(final=final)

    def flush(self):
        """Complete everything (end of a recording or of the monitor)."""
        for run in list(self.runs):
            if run.t1_s is None:
                run.t1_s = self._last_t1(run)
            self._complete(run)
        if not self.seen_records and self.loose_t:
            self._signal_passages(final=True)

    # ------------------------------------------------------------------ internals
    @staticmethod
    def _last_t1(run):
        """A run's end when its ``done`` never came: its last sample's stamp."""
        return run.t0_s + ((run.t[-1] - run.t0_s) / run.scale if run.t else 0.0)

    def _run(self, run_id):
        return next((r for r in self.runs if r.run_id == run_id), None)

    @staticmethod
    def _put(run, t, a):
        run.t.append(run.t0_s + (t - run.t0_s) * run.scale)
        run.a.append(a)

    def _limit(self):
        track = self.track_type or self.bridge_track or "ballasted"
        if self.track_type is None and self.bridge_limit is not None:
            return self.bridge_limit, track
        return acc_limit_m_s2(track), track

    def _emit(self, t, a, t_free_s, source, run_id=None, phase=None, info=None, before=None, after=None):
        limit, track = self._limit()
        p = analyse_passage(t, a, index=len(self.passages) + 1, limit_m_s2=limit, track_type=track,
                            warn_fraction=self.warn_fraction, t_free_s=t_free_s, settings=self.settings,
                            source=source, run_id=run_id, phase=phase, info={"track_type": track, **(info or {})},
                            before=before, after=after, dynamic=source == "run records")
        self.passages.append(p)
        if self.on_passage is not None:
            self.on_passage(p)
        return p

    def _complete(self, run):
        self.runs.remove(run)
        self.completed.add(run.run_id)
        if self.loose_t:  # samples left before this run's end belong to no run
            t = np.asarray(self.loose_t)
            keep = t >= run.t1_s - STAMP_TOLERANCE_S
            self.dropped += int((~keep).sum())
            self.loose_t = t[keep].tolist()
            self.loose_a = np.asarray(self.loose_a)[keep].tolist()
        if run.failed is not None:
            return
        t_free = None
        if run.speed_m_s and self.span_m is not None and self.train_length_m is not None:
            t_free = run.t0_s + (self.train_length_m + self.span_m) / run.speed_m_s
        info = {"bridge": self.bridge_name, "t_train_left_s": t_free, "samples_published": run.published,
                "samples_lost": None if run.published is None else max(run.published - len(run.t), 0)}
        self._emit(np.asarray(run.t), np.asarray(run.a), t_free, "run records", run.run_id,
                   self.phases.get(run.run_id), info)

    def _signal_passages(self, final):
        """Segment the samples without a run; report the passages followed by ``quiet_s`` of quiet
        signal (all at ``final``). The last reported passage stays in the buffer, so the trigger of
        the next segmentation (``min(trigger_snr σ_n, trigger_fraction max)``) sees it as the
        segmentation of the whole record would, and is not pulled down to its decaying tail."""
        t, a = np.asarray(self.loose_t), np.asarray(self.loose_a)
        segs = segment_signal(t, a, self.settings)
        order = np.argsort(t, kind="stable")
        t, a = t[order], a[order]
        last_b = None
        for (b, e), (tp, ap, bf, af) in zip(segs, signal_analyses(t, a, segs, self.settings)):
            if self._reported_until is not None and t[b] <= self._reported_until:
                continue  # reported before (its end may move a little as the buffer grows)
            if not final and t[-1] - t[e - 1] < self.quiet_s:
                break  # may go on
            self._emit(tp, ap, None, "signal", before=bf, after=af)
            self._reported_until, last_b = float(t[e - 1]), b
        if final:
            self.loose_t, self.loose_a = [], []
            self._reported_until = None
        elif last_b is not None or (t.size and t[-1] - t[0] > self.max_buffer_s):
            # keep the last reported passage and what follows; drop what is older or too old
            keep = t >= max(t[last_b] if last_b is not None else t[0], t[-1] - self.max_buffer_s)
            self.loose_t, self.loose_a = t[keep].tolist(), a[keep].tolist()


def run_topics_for(topic):
    """The run-record and description topics beside an acceleration topic of ours
    (``/b1/adm/midspan/accel`` -> ``/b1/adm/run/status``, ``/b1/adm/bridge/description``,
    ``/b1/adm/train/description``), or None for another topic (a sensor's: no run records)."""
    if not topic.endswith(P.TOPIC_ACCEL):
        return None
    ns = topic[: len(topic) - len(P.TOPIC_ACCEL)]
    return ns + P.TOPIC_STATUS, ns + P.TOPIC_BRIDGE_DESC, ns + P.TOPIC_TRAIN_DESC


def _stamp_scale(started):
    """Factor from stamp intervals to the monitored lane's time. A ``started`` record that names the
    lane its stamps run in (``time_lane``) has stamps in the monitored lane's own time; an older one
    stamps in the clock lane's (the slowest: ``clock_speed_kmh``), scaled here by its speed over the
    monitored lane's (``monitor_speed_kmh``), so the frequency of a sweep's monitored lane comes out
    right."""
    if started.get("time_lane") is not None:
        return 1.0
    v_mon, v_clock = started.get("monitor_speed_kmh"), started.get("clock_speed_kmh")
    if v_mon and v_clock:
        return float(v_clock) / float(v_mon)
    return 1.0
