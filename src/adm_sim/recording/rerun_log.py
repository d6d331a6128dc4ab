"""Visualise adm-sim runs with rerun 0.41: set-up (loopback only, analytics off) and :class:`RunLogger`.

Time always comes from the simulation, never from the wall clock. Timelines: ``sim_time``
(session sim time in s, from message stamps; continuous over the runs of a session),
``run_time`` (s since the first axle entered the bridge, in the monitored lane's own time; 0 at
every run start, so that runs overlay), ``speed_kmh`` (speed sweeps) and ``iteration``
(calibration steps). Whole arrays go through ``rr.send_columns``.

Every recording carries the default blueprint of :mod:`adm_sim.recording.rerun_blueprint` (tabs
``Runs``, ``Speed sweep``, ``Calibration``), sent by :class:`RunLogger` as soon as the bridge's
span is known. Entities
--------
``runs/acceleration/run_NN``
    Midspan acceleration [m/s²] of the monitored lane of run NN, on ``sim_time`` and ``run_time``.
``runs/beam/run_NN/deflection``, ``runs/beam/run_NN/axles``, ``runs/beam/supports``
    Deflected beam (x along the span in m, deflection in m times the exaggeration; rerun's 2D y
    axis points down, so a sag shows below the axis) and the axles on it; cleared when the run ends.
``runs/info``
    Table of the runs: series, lanes, monitored speed, sampling, peak.
``sweep/curves/{DIM,MLM_zeta,MLM_zeta_dz}``, ``sweep/trials/{bracketing,root_search}/NN``
    Maximum deck acceleration [m/s²] against speed, one entity per curve and per damping trial. The
    run's phase (:data:`adm_sim.protocol.PHASES`) picks the entity; every caller hands it over
    (:meth:`RunLogger.run_done`, :meth:`RunLogger.iteration`), nothing is read from array shapes.
    Runs of a recording made before runs carried their phase go to ``sweep/curves/unknown[_run_NN]``.
``calibration/delta_zeta_pct/*``, ``calibration/peak_m_s2/*``, ``calibration/result``
    Δζ per iteration, MLM and DIM peaks, bracketing and root search as separate series.

Set-up
------
:func:`init_rerun` opens the recording with rerun's analytics off and every server on the loopback;
the rerun processes beside it (the ``rerun`` executable, the analytics opt-out, a spawned viewer, its
ports, the loopback check of a viewer URL) are :mod:`adm_sim.recording.viewer_process`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr

from adm_sim import protocol as P  # topics, records, phases, entity paths, timelines
from adm_sim.errors import InputError
from adm_sim.protocol import RUN_TIME, SIM_TIME
from adm_sim.recording import rerun_blueprint as bp
from adm_sim.recording.viewer_process import check_loopback, close_watched, ensure_analytics_disabled, handshake, spawn_viewer

__all__ = [
    "close_rerun",
    "init_rerun",
    "RunLogger",
    "fmt_pct",
    "run_kind",
    "supports_m",
]

# ---------------------------------------------------------------- set-up


def init_rerun(app_id: str, spawn: bool = False, connect_url: str | None = None,
               save_path=None, overwrite: bool = False, recording_id: str | None = None):
    """Start a rerun recording with analytics off and servers on the loopback only.

    Parameters
    ----------
    app_id : str
        Application id, e.g. ``"adm_sim"``.
    spawn : bool
        Start a native viewer bound to 127.0.0.1 and stream to it.
    connect_url : str or None
        Stream to a running viewer, e.g. ``"rerun+http://127.0.0.1:9876/proxy"`` (loopback only).
    save_path : path-like or None
        Also (or only) write an ``.rrd`` file; an existing one is refused unless ``overwrite``.
    recording_id : str or None
        Fixed recording id (several processes logging into one recording).

    Returns
    -------
    rerun.RecordingStream
        The global recording; the ``log_*`` functions log to it unless given ``recording=``.
        A spawned viewer is detached (its own session) and outlives this process.

    With no sink at all the data are buffered in memory (``rr.init`` default behaviour).
    """
    ensure_analytics_disabled()
    sinks: list = []
    if spawn and connect_url is not None:
        raise InputError("init_rerun: give spawn=True or connect_url, not both")
    if spawn:  # listening, answering the handshake and still alive a moment later, or RunError
        _, connect_url = spawn_viewer()  # the viewer process is held by viewer_process until exit
    elif connect_url is not None:  # a closed port, another server or silence: RunError, one line
        handshake(check_loopback(connect_url), what="connect_url")
    if connect_url is not None:
        sinks.append(rr.GrpcSink(check_loopback(connect_url)))
    if save_path is not None:
        save_path = Path(save_path)
        if save_path.exists() and not overwrite:
            raise InputError(f"save_path: '{save_path}' already exists; refusing to overwrite it "
                             "(pass overwrite=True or choose another file)")
        if save_path.suffix != ".rrd":
            raise InputError(f"save_path: '{save_path}' must end in .rrd")
        sinks.append(rr.FileSink(str(save_path)))
    rr.init(app_id, recording_id=recording_id, spawn=False)
    if sinks:
        rr.set_sinks(*sinks)
    rec = rr.get_global_data_recording()
    # simulated time only: no wall-clock ``log_time`` timeline in the picker (reproducible files)
    rr.set_log_time_enabled(False, recording=rec)
    _VIEWER_URL[0] = connect_url
    return rec


#: The viewer the global recording streams to (set by :func:`init_rerun`).
_VIEWER_URL: list[str | None] = [None]


def close_rerun(recording=None, watch_viewer: bool = False) -> bool:
    """Flush and close the sinks of the recording (the ``.rrd`` file is complete afterwards).

    ``watch_viewer``: when the recording streams to a viewer, the flush runs under
    :func:`~adm_sim.recording.viewer_process.close_watched`: a viewer that stopped answering is
    given up with one ``warning:`` line instead of a hang (returns ``False``; the process should
    then end with :func:`~adm_sim.recording.viewer_process.exit_if_abandoned`).
    """
    url, _VIEWER_URL[0] = _VIEWER_URL[0], None
    if not watch_viewer or url is None:
        rr.disconnect(recording=recording)
        return True
    return close_watched(lambda: rr.disconnect(recording=recording), url)


def _part(label) -> str:
    return rr.escape_entity_path_part(str(label))


# ---------------------------------------------------------------- run logger

#: Series kinds of a run (the viewer name of its phase, :data:`adm_sim.protocol.PHASE_NAMES`) and their
#: colours; ``UNKNOWN``: a run of a recording made before runs carried their phase.
DIM, MLM_ZETA, MLM_ZETA_DZ, BRACKETING, ROOT_SEARCH, UNKNOWN = (
    P.PHASE_NAMES[p][0] for p in (P.PHASE_DIM, P.PHASE_MLM_ZETA, P.PHASE_MLM_ZETA_DZ, P.PHASE_BRACKETING,
                                  P.PHASE_ROOT_SEARCH, P.PHASE_UNKNOWN))
_COLORS = {DIM: (214, 39, 40), MLM_ZETA: (31, 119, 180), MLM_ZETA_DZ: (44, 160, 44),
           BRACKETING: (150, 150, 150), ROOT_SEARCH: (255, 127, 14), UNKNOWN: (90, 90, 90)}
#: Series kind of each run phase (:data:`adm_sim.protocol.PHASES` and ``PHASE_UNKNOWN``).
_KIND_OF_PHASE = {phase: names[0] for phase, names in P.PHASE_NAMES.items()}


def run_kind(phase: str) -> str:
    """Series kind of a run of ``phase`` (:data:`adm_sim.protocol.PHASES` or ``PHASE_UNKNOWN``): its
    display name. Raises :class:`InputError` for any other phase."""
    try:
        return _KIND_OF_PHASE[phase]
    except KeyError:
        raise InputError(f"phase: {phase!r} is not a run phase; allowed "
                         f"{', '.join(_KIND_OF_PHASE)}") from None


def fmt_pct(fraction: float) -> str:
    """A damping fraction as a signed percentage at 1e-4 % (Δζ is solved to 1e-6 %)."""
    return f"{100.0 * fraction:+.4f} %"


def _fmt(x, digits=4) -> str:
    """A number at ``digits`` significant digits (no 1.8500000000000003)."""
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (float, np.floating)):
        return str(x)
    return f"{x:.{digits}g}"


class _Run:
    """One run as the bridge announced it (``/adm/run/status`` ``started``)."""

    def __init__(self, st: dict, t0_s: float):
        self.id = int(st["run_id"])
        self.model = str(st.get("model", "?"))
        self.n_steps = int(st.get("n_steps", 0))
        self.n_lanes = int(st.get("n_lanes", 0))
        self.ds_m = float(st.get("ds_m", 0.0))
        self.t0 = float(st.get("t0_s", t0_s))
        v_clock = float(st.get("clock_speed_kmh", 0.0))
        v_mon = float(st.get("monitor_speed_kmh", 0.0))
        #: run time = (sim time - t0) * scale: the monitored lane's own time since train entry
        self.scale = v_clock / v_mon if v_clock > 0 and v_mon > 0 else 1.0
        self.mon_kmh = v_mon or None
        self.every = st.get("monitor_every_steps")
        self.beam_every = st.get("beam_every_steps")
        # sim time at the run's last step (the clock runs in the slowest lane)
        self.t1 = self.t0 + (self.n_steps * self.ds_m / (v_clock / 3.6) if v_clock > 0 else np.inf)
        self.tag = P.run_tag(self.id)
        self.kind: str | None = None
        self.row: str | None = None
        self.peak: tuple | None = None  # (max |w| [m], x, w, axle x, axle w) of the frame with the largest deflection
        self.dt_clock = self.ds_m / (v_clock / 3.6) if v_clock > 0 else 0.0  # sim time per step
        self.n_frames = 0

    def frames_left(self) -> int:
        """Beam frames still to come: steps 0, b, 2b, ... < n_steps (b = beam_every_steps)."""
        if not self.beam_every or self.n_steps <= 0:
            return 0
        return (self.n_steps - 1) // int(self.beam_every) + 1 - self.n_frames

    def contains(self, t_s: float) -> bool:
        """A sample stamped ``t_s`` is this run's: its steps 0 .. n_steps - 1 lie in [t0, t1), and
        the next run starts at this run's t1 (the session clock goes on), so the bound is half a
        step below t1: a first sample of the next run that arrives before the next run's
        ``started`` record is kept for it, not given to this run."""
        return self.t0 - 1e-9 <= t_s < self.t1 - 0.5 * self.dt_clock

    def run_time(self, t_s):
        return (np.asarray(t_s, dtype=float) - self.t0) * self.scale


def supports_m(bridge: dict) -> list[float]:
    """Support abscissae (m from the left abutment) of the ``bridge`` record of a bridge description:
    ``0`` and ``span_m`` for one simply supported span; ``0`` and the running sums of ``spans_m``
    for a continuous deck (whose ``span_m`` is the deck length, their sum)."""
    spans = [float(x) for x in bridge.get("spans_m") or ()]
    if not spans:
        return [0.0, float(bridge["span_m"])]
    return [0.0, *np.cumsum(spans).tolist()]


class RunLogger:
    """Logs the monitoring stream of an adm-sim session to rerun in the default layout.

    One object per recording, fed with the messages of the ROS graph in the order they arrive:
    live by :class:`adm_sim.nodes.driver.RunDriver`, from an MCAP file by ``replay.py``. Entity
    paths and views: :mod:`adm_sim.recording.rerun_blueprint`. Samples are buffered and logged by
    :meth:`flush` (the driver calls it on every progress tick and at the end of a run), each on
    ``sim_time`` and on ``run_time`` (s since the first axle entered the bridge, in the monitored
    lane's own time: ``(t - t0) v_clock / v_monitored``, 0 at every run start).

    Parameters
    ----------
    recording : rerun.RecordingStream or None
        Target recording (default: the global one).
    exaggeration : float
        Display factor on beam deflections.
    """

    def __init__(self, recording=None, exaggeration: float | None = None):

        self.rec = recording
        self.exaggeration = float(bp.BEAM_EXAGGERATION if exaggeration is None else exaggeration)
        self.runs: list[_Run] = []
        self._acc: list[tuple[float, float]] = []
        self._beam: list[tuple] = []
        self._beam_run = 0  # index of the run the next beam frame belongs to
        self._span_m: float | None = None
        self._bridge: dict = {}
        self._train: dict = {}
        self._trials = {phase: 0 for phase in P.TRIAL_PHASES}
        self._curves_used: set[str] = set()
        self._styled: set[str] = set()
        self.blueprint_sent = False

    # ------------------------------------------------------------ helpers
    def _style(self, path, lines=True, name=None, color=None, width=None, visible=None):
        """Name, colour and width of a series (static, once per entity)."""
        if path in self._styled:
            return
        self._styled.add(path)
        if lines:
            arch = rr.SeriesLines(names=name, colors=color, widths=width, visible_series=visible)
        else:
            arch = rr.SeriesPoints(names=name, colors=color, marker_sizes=width)
        rr.log(path, arch, static=True, recording=self.rec)

    def send_blueprint(self, active_tab: str = "Runs"):
        """Send the default blueprint (again, e.g. once the span is known)."""
        rr.send_blueprint(bp.default_blueprint(self._span_m, self.exaggeration, active_tab), make_active=True,
                          make_default=True, recording=self.rec)
        self.blueprint_sent = True

    # ------------------------------------------------------------ descriptions
    def bridge_description(self, desc: dict):
        """``/adm/bridge/description``: the deck length (``span_m``) fixes the beam view; a support is
        drawn at each end and, for a continuous deck, over every intermediate pier (:func:`supports_m`)."""
        self._bridge = desc
        span = float(desc.get("bridge", {}).get("span_m", 0.0)) or None
        if span is None or span == self._span_m:
            return
        self._span_m = span
        self.send_blueprint()
        h = 0.04 * span
        tri = [[[x - h, h * 1.2], [x, 0.0], [x + h, h * 1.2], [x - h, h * 1.2]] for x in supports_m(desc["bridge"])]
        rr.log(P.beam_path(part="supports"), rr.LineStrips2D(tri, colors=(60, 60, 60), radii=0.02), static=True,
               recording=self.rec)
        rr.log(P.beam_path(part="axis"), rr.LineStrips2D([[[0.0, 0.0], [span, 0.0]]], colors=(180, 180, 180), radii=0.01),
               static=True, recording=self.rec)

    def train_description(self, desc: dict):
        self._train = desc

    # ------------------------------------------------------------ samples
    def run_started(self, st: dict):
        """``/adm/run/status`` with ``state`` = ``started`` from the bridge."""
        if not P.is_bridge_start(st):
            return
        if any(r.id == int(st["run_id"]) for r in self.runs):
            return
        t0 = self.runs[-1].t1 if self.runs and np.isfinite(self.runs[-1].t1) else 0.0
        self.runs.append(_Run(st, t0))

    def accel(self, t_s: float, acc_m_s2: float):
        """One ``/adm/midspan/accel`` sample (sim time in s, acceleration of the monitored lane)."""
        self._acc.append((float(t_s), float(acc_m_s2)))

    def beam(self, t_s: float, x_m, w_m, axle_x_m, axle_w_m):
        """One ``/adm/beam/deflection`` + ``/adm/beam/axles`` frame (positions and deflections in m).

        ``t_s`` (the clock when it was received) is not used: see :meth:`flush`.
        """
        self._beam.append((float(t_s), np.asarray(x_m, float), np.asarray(w_m, float),
                           np.asarray(axle_x_m, float), np.asarray(axle_w_m, float)))

    def _owner(self, t_s):
        for r in reversed(self.runs):
            if r.contains(t_s):
                return r
        return None

    def flush(self):
        """Log the buffered samples of every announced run; keep those of runs not yet announced."""
        if not self.runs:
            return
        latest = self.runs[-1].t0
        groups: dict[int, list] = {}
        keep = []
        for t, a in self._acc:
            r = self._owner(t)
            if r is not None:
                groups.setdefault(r.id, []).append((t, a))
            elif t > latest:
                keep.append((t, a))
        self._acc = keep
        by_id = {r.id: r for r in self.runs}
        for rid, samples in groups.items():
            r = by_id[rid]
            t = np.array([s[0] for s in samples])
            a = np.array([s[1] for s in samples])
            rr.send_columns(P.acceleration_path(r.id),
                            indexes=[rr.TimeColumn(SIM_TIME, duration=t),
                                     rr.TimeColumn(RUN_TIME, duration=r.run_time(t))],
                            columns=rr.Scalars.columns(scalars=a), recording=self.rec)
        # beam frames carry no stamp: the j-th frame of a run is its step j * beam_every (frames of
        # one topic arrive in order), so frames are dealt to the announced runs in turn
        k = self.exaggeration
        frames: dict[int, tuple] = {}  # run id -> (run, [(sim ns, run ns, strip, axle points)])
        n_taken = 0
        while n_taken < len(self._beam):
            while self._beam_run < len(self.runs) and self.runs[self._beam_run].frames_left() == 0:
                self._beam_run += 1
            if self._beam_run >= len(self.runs):
                break
            r = self.runs[self._beam_run]
            _, x, w, ax, aw = self._beam[n_taken]
            n_taken += 1
            step = r.n_frames * int(r.beam_every)
            r.n_frames += 1
            if w.size and (r.peak is None or np.max(np.abs(w)) > r.peak[0]):
                r.peak = (float(np.max(np.abs(w))), x, w, ax, aw)
            t = r.t0 + step * r.dt_clock
            # rerun's 2D y axis points down: a sag (w > 0, downward) is drawn below the axis
            frames.setdefault(r.id, (r, []))[1].append((
                round(1e9 * float(t)), round(1e9 * float(r.run_time(t))),  # as rr.set_time rounds
                np.column_stack([x, k * w]), np.column_stack([ax, k * aw]).reshape(-1, 2)))
        del self._beam[:n_taken]
        # one column of frames per run and part (rr.send_columns): the rows rr.log would write, one
        # per frame with its strip or axle points, colour and radius, at the same two times
        for r, fr in frames.values():
            path = P.beam_path(r.id)
            color = _COLORS.get(r.kind, (90, 90, 90))
            n = len(fr)
            index = [rr.TimeColumn(SIM_TIME, duration=np.array([f[0] for f in fr], dtype="timedelta64[ns]")),
                     rr.TimeColumn(RUN_TIME, duration=np.array([f[1] for f in fr], dtype="timedelta64[ns]"))]
            rr.send_columns(f"{path}/deflection", indexes=index, recording=self.rec,
                            columns=rr.LineStrips2D.columns(strips=[f[2] for f in fr], colors=[color] * n,
                                                            radii=[0.03] * n))
            points = [f[3] for f in fr]
            rr.send_columns(f"{path}/axles", indexes=index, recording=self.rec,
                            columns=[*rr.Points2D.columns(positions=np.concatenate(points)).partition(
                                         [len(p) for p in points]),
                                     *rr.Points2D.columns(colors=[color] * n, radii=[0.12] * n)])
        rr.reset_time(recording=self.rec)

    # ------------------------------------------------------------ end of a run
    def run_done(self, result, phase: str, run_id: int | None = None) -> str | None:
        """``/adm/run/result`` (rows speed_kmh, max_acc_m_s2, max_disp_m, delta_zeta): log the curves.

        ``phase`` is the run's phase as the caller was handed it (:data:`adm_sim.protocol.PHASES`,
        ``PHASE_UNKNOWN`` for an old recording); it is never read from the arrays. ``run_id``: the
        run the result belongs to (default the last announced one). Returns the run's kind
        (:func:`run_kind`), ``None`` if the run was never announced.
        """
        self.flush()
        res = np.asarray(result, dtype=float)
        runs = [r for r in self.runs if run_id is None or r.id == int(run_id)]
        if not runs:
            return None
        r = runs[-1]
        if r.kind is not None:  # a result twice (replay of a duplicated record)
            return r.kind
        v, acc, dz = res[0], res[1], res[3]
        r.kind = kind = run_kind(phase)
        color = _COLORS[kind]
        mon = f" at {r.mon_kmh:g} km/h" if r.mon_kmh else ""
        uniq = np.unique(dz)
        dz_txt = f", Δζ {fmt_pct(uniq[0])}" if uniq.size == 1 and uniq[0] != 0.0 else (
            f", {uniq.size} Δζ" if uniq.size > 1 else "")
        # the ladder's history is that of its first rung (the lowest Δζ): hidden until asked for
        self._style(P.acceleration_path(r.id), name=f"run {r.id} {kind}{dz_txt}{mon}", color=color,
                    width=2.0 if kind in (DIM, MLM_ZETA, MLM_ZETA_DZ) else 1.0,
                    visible=[False] if kind == BRACKETING else None)
        # when the run ends its moving beam gives way to its shape at the largest deflection
        rr.set_time(SIM_TIME, duration=r.t1, recording=self.rec)
        rr.set_time(RUN_TIME, duration=float(r.run_time(r.t1)), recording=self.rec)
        for part in ("deflection", "axles"):
            rr.log(P.beam_path(r.id, part), rr.Clear(recursive=False), recording=self.rec)
        if r.peak is not None:
            _, x, w, ax, aw = r.peak
            k = self.exaggeration
            rr.log(P.beam_path(r.id, "peak_shape"), rr.LineStrips2D([np.column_stack([x, k * w])], colors=color,
                                                                    radii=0.03), recording=self.rec)
            rr.log(P.beam_path(r.id, "peak_axles"), rr.Points2D(np.column_stack([ax, k * aw]).reshape(-1, 2),
                                                                colors=color, radii=0.12), recording=self.rec)
        rr.reset_time(recording=self.rec)
        self._log_limit(r)
        self._log_sweep(r, phase, kind, v, acc, dz)
        i = int(np.argmax(acc))
        r.row = (f"| {r.id} | {kind}{dz_txt} | {v.size} | {_fmt(v.min())}–{_fmt(v.max())} | "
                 f"{_fmt(r.mon_kmh) if r.mon_kmh else '-'} | {self._sampling(r)} | {acc[i]:.3f} | {v[i]:g} |")
        self._log_run_table()
        return kind

    def _log_limit(self, r: _Run):
        """The EN 1990 A2.4.4.2.1 limit of the bridge's track (its description's ``acc_limit_m_s2``)
        as two lines, +limit and -limit, over the run's run time (``runs/acceleration/limit_*``):
        the samples are signed (z up), the limit bounds their magnitude."""
        limit = float(self._bridge.get("acc_limit_m_s2") or 0.0)
        if limit <= 0.0 or not np.isfinite(r.t1):
            return
        track = str(self._bridge.get("track_type", "")).replace("_", " ")
        t_run = np.array([0.0, float(r.run_time(r.t1))])
        t_sim = np.array([r.t0, r.t1])
        for sign, part in ((1.0, "limit_upper"), (-1.0, "limit_lower")):
            path = f"{P.ENTITIES['acceleration']}/{part}"
            self._style(path, name=f"EN 1990 A2.4.4.2.1 limit {'+' if sign > 0 else '-'}{limit:g} m/s² ({track})",
                        color=(200, 0, 0), width=1.0)
            rr.send_columns(path, indexes=[rr.TimeColumn(SIM_TIME, duration=t_sim),
                                           rr.TimeColumn(RUN_TIME, duration=t_run)],
                            columns=rr.Scalars.columns(scalars=sign * np.full(2, limit)), recording=self.rec)

    def _sampling(self, r: _Run) -> str:
        """Monitoring step of a run in the monitored lane's time, and samples per period of the top mode."""
        if not r.every or not r.mon_kmh or not r.ds_m:
            return "- | -"
        dt = int(r.every) * r.ds_m / (r.mon_kmh / 3.6)
        n0 = float(self._bridge.get("n0_hz", 0.0))
        nm = int(self._bridge.get("bridge", {}).get("n_modes", 0))
        per = f"{1.0 / (nm * nm * n0 * dt):.1f}" if n0 > 0 and nm > 0 else "-"
        return f"{dt * 1e3:.2f} | {per}"

    def _log_run_table(self):
        b = self._bridge.get("description", "")
        t = self._train.get("name", self._train.get("train", ""))
        head = f"**{b}**  \n**train** {t}\n\n" if b or t else ""
        rows = "\n".join(r.row for r in self.runs if r.row)
        nm = self._bridge.get("bridge", {}).get("n_modes", "n")
        text = (head + f"| run | series | lanes | speeds [km/h] | monitored [km/h] | Δt [ms] | per T{nm} | "
                "max a [m/s²] | at [km/h] |\n|---|---|---|---|---|---|---|---|---|\n" + rows + "\n\n"
                f"Δt: monitoring step in the monitored lane's time; per T{nm}: samples per period of mode {nm} "
                "(the highest retained).\n")
        rr.log(P.ENTITIES["run_info"], rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True,
               recording=self.rec)

    def _log_sweep(self, r: _Run, phase: str, kind: str, v, acc, dz):
        if phase in P.TRIAL_PHASES:
            for value in np.unique(dz):
                lanes = dz == value
                self._trials[phase] += 1
                n = self._trials[phase]
                path = P.sweep_trial_path(phase, n)
                self._style(path, name=f"{'bracket' if kind == BRACKETING else 'root'} {n}: Δζ {fmt_pct(value)}",
                            color=_COLORS[kind], width=1.0)
                self._send_curve(path, v[lanes], acc[lanes])
            return
        name = P.SWEEP_CURVE_NAMES[phase]
        if kind != DIM and name in self._curves_used:
            name = f"{name}_{r.tag}"
        self._curves_used.add(name)
        uniq = np.unique(dz)
        label = kind + (f" (Δζ {fmt_pct(uniq[0])})" if kind == MLM_ZETA_DZ else "")
        for trials in (False, True) if kind in (DIM, MLM_ZETA_DZ) else (False,):
            path = P.sweep_curve_path(name, trials)
            # the DIM runs on a window of the speed grid (docs/ros.md): its values as points, so
            # that no line is drawn across the speeds it did not compute
            self._style(path, lines=kind != DIM, name=label, color=_COLORS[kind], width=2.0 if kind != DIM else 4.0)
            self._send_curve(path, v, acc)

    def _send_curve(self, path, speeds_kmh, max_acc_m_s2):
        v = np.asarray(speeds_kmh, dtype=float)
        order = np.argsort(v, kind="stable")
        rr.send_columns(path, indexes=[rr.TimeColumn(P.SPEED, sequence=np.rint(v[order]).astype(np.int64))],
                        columns=rr.Scalars.columns(scalars=np.asarray(max_acc_m_s2, dtype=float)[order]),
                        recording=self.rec)

    # ------------------------------------------------------------ calibration
    def iteration(self, i: int, delta_zeta_pct: float, mlm_peak_m_s2: float, dim_peak_m_s2: float, phase: str):
        """``/adm/calibration/iteration``: one trial damping of the run of ``phase`` it came from
        (``bracketing``: points, ``root_search``: lines, handed on by the caller like the run's)."""
        kind = run_kind(phase)
        bracketing = phase == P.PHASE_BRACKETING
        color = _COLORS[kind]
        lines = not bracketing
        words = {BRACKETING: "bracketing ladder", ROOT_SEARCH: "root search"}.get(kind, kind)
        dz_path, mlm_path, dim_path = P.delta_zeta_path(phase), P.peak_path(f"mlm_{phase}"), P.peak_path("dim")
        self._style(dz_path, lines=lines, name=f"Δζ, {words} [%]", color=color, width=2.0 if lines else 6.0)
        self._style(mlm_path, lines=lines, name=f"MLM ζ+Δζ peak, {words}", color=color, width=2.0 if lines else 6.0)
        self._style(dim_path, name="DIM peak (target)", color=_COLORS[DIM], width=2.0)
        rr.set_time(P.ITERATION, sequence=int(i), recording=self.rec)
        rr.log(dz_path, rr.Scalars(float(delta_zeta_pct)), recording=self.rec)
        rr.log(mlm_path, rr.Scalars(float(mlm_peak_m_s2)), recording=self.rec)
        rr.log(dim_path, rr.Scalars(float(dim_peak_m_s2)), recording=self.rec)
        rr.reset_time(recording=self.rec)

    def calibration_result(self, d: dict):
        """``/adm/calibration/result`` (``CalibrationResult.to_dict()``) as a markdown table."""
        units = {"zeta_pct": "%", "delta_zeta_vbi_pct": "%", "delta_zeta_adm_pct": "%", "delta_zeta_eada_pct": "%",
                 "delta_zeta_lb_pct": "%"}
        rows = []
        for k in ("bridge_description", "bridge", "train", "status", "message", "zeta_pct", "delta_zeta_vbi_pct",
                  "delta_zeta_adm_pct", "delta_zeta_eada_pct", "delta_zeta_lb_pct"):
            if k in d and d[k] not in (None, ""):
                val = d[k]
                val = f"{val:.4f}" if isinstance(val, float) else str(val)
                rows.append(f"| {k} | {val} {units.get(k, '')} |")
        for k in ("mlm_peak", "dim_peak", "adapted_mlm_peak"):
            p = d.get(k)
            if isinstance(p, dict) and p.get("acc_m_s2") is not None:
                rows.append(f"| {k} | {p['acc_m_s2']:.4f} m/s² at {p['speed_kmh']:g} km/h |")
        rr.log(P.ENTITIES["cal_result"], rr.TextDocument("| | |\n|---|---|\n" + "\n".join(rows) + "\n",
                                                     media_type=rr.MediaType.MARKDOWN),
               static=True, recording=self.rec)
