"""Figures of the calibration (matplotlib, Agg backend), kept outside the analysis.

* :func:`plot_calibration`: analogue of paper Fig. 15, maximum midspan acceleration against
  speed for the MLM, the DIM and the MLM with ``zeta + Δζ_VBI``, peaks marked.
* :func:`plot_total_damping`: analogue of paper Fig. 19, total damping ``zeta + Δζ`` per bridge and
  approach (VBI, LB, ADM, EADA), one panel per train.
"""

from __future__ import annotations

import math

APPROACHES = ("VBI", "LB", "ADM", "EADA")
COLOURS = {"VBI": "tab:blue", "LB": "tab:orange", "ADM": "gold", "EADA": "tab:purple"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def plot_calibration(result, path):
    """Write the Fig. 15 analogue of a :class:`~adm_calib.calibrate.CalibrationResult` to ``path``."""
    plt = _pyplot()
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
    plt = _pyplot()
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
