"""Default rerun layout of an adm-sim recording: three tabs, one per question.

Every recording written or streamed by adm-sim (``calibrate.py``, ``crossing.py``, ``replay.py``)
carries this blueprint, so the viewer opens on it instead of guessing a layout.

Tabs
----
``Runs``
    Midspan acceleration of every run over ``run_time`` (s since the first axle entered the
    bridge, in the monitored lane's own time, so that runs overlay) beside the deflected beam with
    its supports, fixed bounds and the display exaggeration in the title; under them, the full
    width, the run table.
``Speed sweep``
    Maximum deck acceleration against train speed on ``speed_kmh``: DIM, MLM ζ and the calibrated
    MLM ζ+Δζ on one plot; every damping trial of the calibration its own series, named by its Δζ.
``Calibration``
    Δζ per iteration (all, and the root search alone on its own scale) and the MLM peak against the
    DIM peak on ``iteration``, the bracketing ladder and the root search as separate series; the
    calibration result.

A time series view plots against the viewer's one selected timeline, which is shared by all
tabs; the blueprint opens on ``run_time`` (the ``Runs`` tab) and every view of another tab names
the timeline it needs in its title.
"""

from __future__ import annotations

import rerun.blueprint as rrb

__all__ = ["BEAM_EXAGGERATION", "ENTITIES", "TABS", "TIMELINES", "default_blueprint", "tab_timeline"]

# timeline names and entity roots: one home, the ROS-free protocol (re-exported here for the views)
from adm_sim.protocol import (ENTITIES, ITERATION, PHASE_ROOT_SEARCH, RUN_TIME, SIM_TIME, SPEED,  # noqa: F401
                              TIMELINES, delta_zeta_path)

#: Display factor on beam deflections (a few mm on a 15 m span are invisible at 1).
BEAM_EXAGGERATION = 500.0

TABS = ("Runs", "Speed sweep", "Calibration")
_TAB_TIMELINE = {"Runs": RUN_TIME, "Speed sweep": SPEED, "Calibration": ITERATION}


def tab_timeline(tab: str) -> str:
    """Timeline the views of ``tab`` plot against."""
    return _TAB_TIMELINE[tab]


def default_blueprint(span_m: float | None = None, exaggeration: float = BEAM_EXAGGERATION,
                      active_tab: str = "Runs"):
    """The default blueprint (``rerun.blueprint.Blueprint``) of an adm-sim recording.

    Parameters
    ----------
    span_m : float or None
        Span of the bridge in m: fixes the bounds of the beam view (x from -5 % to 105 % of the
        span, deflection from -10 % to +20 % (sag) of the span after exaggeration). ``None``: automatic bounds.
    exaggeration : float
        Display factor on the beam deflections, shown in the beam view's title.
    active_tab : str
        Tab shown first (one of :data:`TABS`); the time panel opens on its timeline.
    """
    if active_tab not in TABS:
        raise ValueError(f"active_tab: {active_tab!r} is not one of {', '.join(TABS)}")
    e = ENTITIES
    bounds = None
    if span_m is not None and span_m > 0:
        bounds = rrb.VisualBounds2D(x_range=[-0.05 * span_m, 1.05 * span_m],
                                    y_range=[-0.1 * span_m, 0.2 * span_m])
    # the run table has nine columns and a row per run (a calibration: about a dozen): it gets the full
    # width and 3/5 of the height (beside the beam, in 2/5 of it, the rows past the 8th were cut)
    runs = rrb.Vertical(
        rrb.Horizontal(
            rrb.TimeSeriesView(
                name="Midspan acceleration [m/s²] of every run vs time since train entry [s] (run_time)",
                origin=e["acceleration"], plot_legend=rrb.PlotLegend(corner="RightTop")),
            rrb.Spatial2DView(
                name=f"Deflected beam [m], deflection ×{exaggeration:g}, sag down; a finished run shows "
                     "its largest deflection",
                origin=e["beam"], visual_bounds=bounds, background=[250, 250, 250]),
            column_shares=[3, 2]),
        rrb.TextDocumentView(name="Runs (monitored lane, sampling, peaks)", origin=e["run_info"]),
        row_shares=[2, 3], name="Runs")
    sweep = rrb.Vertical(
        rrb.TimeSeriesView(
            name="Max deck acceleration [m/s²] vs speed [km/h]: DIM, MLM ζ, MLM ζ+Δζ (timeline speed_kmh)",
            origin=e["sweep_main"], plot_legend=rrb.PlotLegend(corner="LeftTop")),
        rrb.TimeSeriesView(
            name="Damping trials: MLM max acceleration [m/s²] vs speed [km/h], one series per Δζ "
                 "(timeline speed_kmh)",
            origin=e["sweep_trials"], plot_legend=rrb.PlotLegend(corner="LeftTop", visible=False)),
        row_shares=[3, 2], name="Speed sweep")
    calibration = rrb.Horizontal(
        rrb.Vertical(
            rrb.TimeSeriesView(name="Δζ [%] per iteration: bracketing ladder, root search (timeline iteration)",
                               origin=e["dz"], plot_legend=rrb.PlotLegend(corner="LeftTop")),
            rrb.TimeSeriesView(name="Δζ [%] of the root search alone, per iteration (timeline iteration)",
                               origin=delta_zeta_path(PHASE_ROOT_SEARCH), plot_legend=rrb.PlotLegend(visible=False)),
            rrb.TimeSeriesView(name="Peak acceleration [m/s²] per iteration: MLM ζ+Δζ vs DIM "
                                    "(timeline iteration)",
                               origin=e["peaks"], plot_legend=rrb.PlotLegend(corner="RightTop")),
            row_shares=[2, 1, 2]),
        rrb.TextDocumentView(name="Calibration result", origin=e["cal_result"]),
        column_shares=[3, 1], name="Calibration")
    return rrb.Blueprint(
        rrb.Tabs(runs, sweep, calibration, active_tab=TABS.index(active_tab)),  # by name: views only
        rrb.TimePanel(timeline=tab_timeline(active_tab), state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        auto_views=False, auto_layout=False)
