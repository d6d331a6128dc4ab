"""Figures of the simulation (matplotlib, Agg backend), kept outside the computations.

The core computes and returns results; the command line draws them: :func:`plot_sweep` for
``adm-sim sweep --plot``, :func:`plot_check` for ``adm-sim check --plot`` / ``adm-calib check --plot``
(the calibration's figures are in :mod:`adm_calib.plots`).
"""

from __future__ import annotations

import numpy as np

from adm_sim.integrate.where import where_text


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (files only, no display), loaded at the first figure."""
    import matplotlib  # noqa: PLC0415  matplotlib loads only when a figure is drawn

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt  # noqa: PLC0415  after the Agg backend is chosen

    return plt


def plot_sweep(result, path, limit=3.5, where="midspan"):
    """A sweep's maximum acceleration against speed, its peak and the EN 1990 limit, as a PNG."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(result.speeds_kmh, result.max_acc_m_s2, lw=1.5, label=result.model.upper())
    pk = result.peak()
    if pk is not None:
        ax.plot([pk["speed_kmh"]], [pk["acc_m_s2"]], "o", color="C3",
                label=f"peak {pk['acc_m_s2']:.3f} m/s² at {pk['speed_kmh']:g} km/h")
    ax.axhline(limit, color="0.5", ls="--", lw=1, label=f"EN 1990 A2 ballasted limit {limit} m/s²")
    ax.set_xlabel("speed (km/h)")
    ax.set_ylabel({"deck": "max |deck acceleration| (m/s²)", "midspan": "max |midspan acceleration| (m/s²)"}.get(
        where, f"max |acceleration| at {where_text(where)} (m/s²)"))
    zeta = "/".join(f"{100 * z:.3g}" for z in np.ravel(result.bridge.modal_damping_ratios(result.delta_zeta)))
    ax.set_title(f"{result.bridge.name or 'bridge'} x {result.train_name} ({result.model.upper()}, "
                 f"{'exact' if result.method == 'exact' else 'RK4'}; zeta per mode {zeta} %)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_check(result, path):
    """The check's envelopes (one curve per train), the limit and the governing case, as a PNG."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 5))
    for i, c in enumerate(result.trains):
        ls = "-" if c.kind == "hslm" else "--"
        ax.plot(c.speeds_kmh, c.max_acc_m_s2, ls, lw=1.1, color=plt.cm.tab20(i % 20), label=c.name)
    t, sp, acc = result.governing
    ax.axhline(result.limit_m_s2, color="C3", lw=1.5, label=f"limit {result.limit_m_s2:g} m/s² ({result.track})")
    ax.plot([sp], [acc], "o", ms=9, mfc="none", mec="k", mew=1.8,
            label=f"governing: {t.name}, {acc:.3f} m/s² at {sp:g} km/h"
                  + ("" if t.x_max_m is None or result.where == "midspan" else f", x = {t.x_max_m:.2f} m"))
    ax.set_xlabel("speed (km/h)")
    ax.set_ylabel({"deck": "max deck acceleration, whole deck (m/s²)",
                   "midspan": "max midspan acceleration (m/s²)"}.get(result.where,
                                                                     f"max acceleration at {result.where_text} (m/s²)"))
    ax.set_title(f"{result.bridge.name or 'bridge'}: EN 1991-2 dynamic check, V = {result.max_line_speed_kmh:g} km/h, "
                 f"damping {result.damping}, {result.damping_model} (zeta per mode {t.zeta_text()} %): "
                 f"{'PASS' if result.passed else 'FAIL'}", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
