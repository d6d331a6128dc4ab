"""Figures of the calibration (matplotlib, Agg backend), kept outside the analysis.

* :func:`plot_calibration`: analogue of paper Fig. 15, maximum midspan acceleration against
  speed for the MLM, the DIM and the MLM with ``zeta + Δζ_VBI``, peaks marked.
* :func:`plot_total_damping`: analogue of paper Fig. 19, total damping ``zeta + Δζ`` per bridge and
  approach (VBI, LB, ADM, EADA), one panel per train.
"""

from __future__ import annotations

import math

import numpy as np

from adm_sim.cli.figures import pyplot

from adm_calib.reference import adm_delta_zeta_pct, lower_bound_table
from adm_calib.study.cases import INTERVAL_EDGES_HZ, LOWER_LIMIT_HZ, MASS_FUNCTION_NAMES, STUDY_TRAINS, paper_train

APPROACHES = ("VBI", "LB", "ADM", "EADA")
COLOURS = {"VBI": "tab:blue", "LB": "tab:orange", "ADM": "gold", "EADA": "tab:purple"}


def plot_calibration(result, path):
    """Write the Fig. 15 analogue of a :class:`~adm_calib.calibration_result.CalibrationResult` to ``path``."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    zeta = result.zeta_pct
    ax.plot(result.mlm_speeds_kmh, result.mlm_acc_m_s2, color="tab:red", lw=1.2, label=f"MLM, zeta={zeta:.2f} %")
    ax.plot(result.dim_speeds_kmh, result.dim_acc_m_s2, color="tab:blue", lw=1.2, marker=".", ms=3,
            label="DIM")
    if result.adapted_speeds_kmh.size:
        ax.plot(result.adapted_speeds_kmh, result.adapted_acc_m_s2, color="tab:green", lw=1.2, ls="--",
                label=f"MLM, zeta + dz_VBI = {zeta:.2f} + {result.delta_zeta_vbi_pct:.3f} %")
    for p, c, m in ((result.mlm_peak, "tab:red", "o"), (result.dim_peak, "tab:blue", "s"),
                    (result.adapted_peak, "tab:green", "D")):
        if p.found:
            ax.plot([p.speed_kmh], [p.acc_m_s2], marker=m, mfc="none", mec=c, ms=9, ls="none")
    ax.set_xlabel("speed v (km/h)")
    ax.set_ylabel("max. midspan acceleration (m/s$^2$)")
    ax.set_title(f"{result.bridge.name or 'bridge'} x {result.train_name}: {result.status}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_total_damping(table, path):
    """Write the Fig. 19 analogue of a :class:`~adm_calib.table4.Table4` to ``path``.

    Grey bars: structural damping zeta; coloured bars on top: Δζ of each approach (drawn downwards
    when negative); "n/a" where the approach is undefined.
    """
    plt = pyplot()
    trains = table.trains
    bridges = table.bridges
    ncol = min(2, len(trains))
    nrow = math.ceil(len(trains) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.0 * ncol, 3.6 * nrow), squeeze=False)
    width = 0.8 / len(APPROACHES)
    for k, train in enumerate(trains):
        ax = axes[k // ncol][k % ncol]
        for j, bridge in enumerate(bridges):
            zeta = table.zeta_pct[bridge]
            for a, approach in enumerate(APPROACHES):
                x = j + (a - (len(APPROACHES) - 1) / 2) * width
                dz = table.value(approach, train, bridge)
                ax.bar(x, zeta, width=width, color="0.75", edgecolor="0.5", lw=0.4)
                if dz is None:
                    ax.text(x, zeta, "n/a", ha="center", va="bottom", fontsize=6, rotation=90)
                else:
                    ax.bar(x, dz, bottom=zeta, width=width, color=COLOURS[approach], edgecolor="0.3", lw=0.4,
                           label=approach if j == 0 else None)
        tops = [table.zeta_pct[b] + max([0.0] + [table.value(a, train, b) or 0.0 for a in APPROACHES])
                for b in bridges]
        ax.set_ylim(0.0, 1.3 * max(tops))
        ax.set_xticks(range(len(bridges)), bridges)
        ax.set_ylabel("zeta_tot = zeta + dz (%)")
        ax.set_title(train)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7, ncol=4, loc="upper right")
    for k in range(len(trains), nrow * ncol):
        axes[k // ncol][k % ncol].axis("off")
    fig.suptitle("Total damping for different approaches (grey: structural zeta)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ---------------------------------------------------------------------- study figures (Figs. 16-18)
_MF_COLOURS = {"mu1": "#4b0082", "mu2": "#8a2be2", "mu3": "#c39bd3",
               "mu4": "#b35900", "mu5": "#ff8c00", "mu6": "#ffc266"}


def plot_dz_vs_span(records, path):
    """Analogue of Fig. 16: Δζ_VBI against span per train with the Eurocode ADM curve."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True, squeeze=False)
    L = np.linspace(4.0, 40.0, 361)
    adm = [adm_delta_zeta_pct(x) for x in L]
    trains = sorted({r["train"] for r in records}, key=lambda t: (STUDY_TRAINS.index(paper_train(t))
                                                                   if paper_train(t) in STUDY_TRAINS else 9, t))
    for ax, t in zip(axes.flat, trains):
        for m in MASS_FUNCTION_NAMES:
            pts = [(r["span_m"], r["delta_zeta_vbi_pct"]) for r in records if r["train"] == t and r["mass_function"] == m]
            if pts:
                a = np.array(pts)
                ax.plot(a[:, 0], a[:, 1], ls="none", marker="o", ms=3, color=_MF_COLOURS[m], label=m)
        ax.plot(L, adm, color="grey", lw=2, label="ADM (EN 1991-2)")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_title(t)
        ax.set_ylabel("dz (%)")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("span L (m)")
    _legend(axes[0, 0], fontsize=7, ncol=2)
    fig.suptitle("Computed additional damping vs the Eurocode ADM (Fig. 16 analogue)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _legend(ax, **kw):
    if ax.get_legend_handles_labels()[0]:
        ax.legend(**kw)


def _draw_set(ax, study_fit, train, m, n0, conservative=None):
    """One (train, mass function) set: Δζ_VBI against n0, interval minima, our fit, the paper's and,
    when given (``{(train, mf): ConservativeFit}``), the conservative bound."""
    recs = [r for r in study_fit.records_used if r["train"] == train and r["mass_function"] == m]
    if recs:
        ax.plot([r["n0_hz"] for r in recs], [r["delta_zeta_vbi_pct"] for r in recs], ls="none", marker=".",
                color="grey", ms=4, label="dz_VBI")
    f = study_fit.fits.get((train, m))
    if f is not None and f.minima:
        ax.plot([p.n0_hz for p in f.minima], [p.delta_zeta_pct for p in f.minima], ls="none", marker="o",
                mfc="gold", mec="k", ms=6, label="interval minima")
    if f is not None and f.fit is not None:
        ax.plot(n0, f.fit.value_pct(n0), color="tab:blue", lw=1.5,
                label=f"our fit (R2 {f.fit.r2:.3f}, root {f.fit.upper_limit_hz:.2f} Hz)")
    p = f.published if f is not None else None
    if p is None:
        p = lower_bound_table().get(paper_train(train), {}).get(m)
    if p is not None:
        ax.plot(n0, p.value_pct(n0), color="tab:red", lw=1.2, ls="--",
                label=f"paper (root {p.upper_limit_hz:.2f} Hz)")
    c = (conservative or {}).get((train, m))
    if c is not None:
        ax.plot(n0, c.value_pct(n0), color="tab:green", lw=1.2, ls="-.",
                label=f"conservative (LP, root {c.upper_limit_hz:.2f} Hz)")
    for e in INTERVAL_EDGES_HZ:
        ax.axvline(e, color="k", lw=0.3, alpha=0.25)
    ax.axhline(0.0, color="k", lw=0.5)
    lo, hi = study_fit.fit_range_hz
    rng = "" if (lo, hi) == (INTERVAL_EDGES_HZ[0], INTERVAL_EDGES_HZ[-1]) else f", fit {lo:g}-{hi:g} Hz"
    ax.set_title(f"{train}, {m} (rule {study_fit.rule}{rng})")
    ax.grid(alpha=0.2)
    _legend(ax, fontsize=6)


def plot_lower_bound_set(study_fit, train, mass_function, path, *, conservative=None):
    """Analogue of Fig. 17: one set with its interval minima, our fit, the published function and
    (optional) the conservative bound."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    _draw_set(ax, study_fit, train, mass_function, np.linspace(LOWER_LIMIT_HZ, 21.0, 400), conservative)
    ax.set_xlabel("n0 (Hz)")
    ax.set_ylabel("dz (%)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_lower_bounds_train(study_fit, train, path, conservative=None):
    """Fig. 17 analogue for the six mass functions of one train (optional: the conservative bounds)."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5), sharex=True, squeeze=False)
    n0 = np.linspace(LOWER_LIMIT_HZ, 21.0, 400)
    for ax, m in zip(axes.flat, MASS_FUNCTION_NAMES):
        _draw_set(ax, study_fit, train, m, n0, conservative)
    for ax in axes[-1]:
        ax.set_xlabel("n0 (Hz)")
    for ax in axes[:, 0]:
        ax.set_ylabel("dz (%)")
    fig.suptitle(f"Lower bound of the additional damping, {train} (Fig. 17 analogue)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_lower_bounds(study_fit, path):
    """Analogue of Fig. 18: fitted (solid) and published (dashed) lower bounds per train."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True, squeeze=False)
    n0 = np.linspace(LOWER_LIMIT_HZ, 21.0, 400)
    pub = lower_bound_table()
    for ax, t in zip(axes.flat, study_fit.trains):
        for m in MASS_FUNCTION_NAMES:
            f = study_fit.fits.get((t, m))
            if f is not None and f.fit is not None:
                ax.plot(n0, f.fit.value_pct(n0), color=_MF_COLOURS[m], lw=1.6, label=f"{m} fit")
            p = pub.get(paper_train(t), {}).get(m)
            if p is not None:
                ax.plot(n0, p.value_pct(n0), color=_MF_COLOURS[m], lw=1.0, ls="--")
        ax.set_title(f"{t} (dashed: paper)")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.grid(alpha=0.3)
        ax.set_ylabel("dz (%)")
    for ax in axes[-1]:
        ax.set_xlabel("n0 (Hz)")
    _legend(axes[0, 0], fontsize=7, ncol=2)
    fig.suptitle("Lower bounds of the additional damping for each train (Fig. 18 analogue)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
