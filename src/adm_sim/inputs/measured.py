"""The way back from measurement to the bridge: ``--measured PASSAGES.json`` (the monitor's ``--json``).

``adm-sim check``, ``adm-calib calibrate`` and ``adm-calib recommend`` take the bridge's first
natural frequency and damping from the passages the monitor identified (``launch_scripts/monitor.py
--json``, :meth:`adm_sim.monitoring.modal_id.Passage.to_dict`), the rest of the bridge (span, mass per
length, modes, damping model, type) from ``--bridge``:

* ``n0`` = the median of the identified ``f1_hz``;
* ``ζ`` = the lower quartile (25 % quantile, linear interpolation) of the identified ``zeta1_pct``:
  damping scatters from passage to passage and a lower value is the conservative side of a dynamic
  check; by construction never above the median (the quantile is the project's choice);
* ``EJ`` from the measured ``n0`` and the given ``μ`` by paper Eq. (18), ``n0 = π / (2 L²) sqrt(EJ / μ)``,
  so the span and the mass stay the design's and the stiffness is what the bridge shows.

Passages used: those with ``identified`` true and finite positive ``f1_hz`` and ``zeta1_pct``,
except runs whose damping is not the bridge's own (phases ``mlm_zeta_dz``, ``bracketing``,
``root_search`` of a calibration carry an added Δζ): those are counted and left out.

Refused (one :class:`InputError` line naming the file): a file that cannot be read, is not JSON or
is not the monitor's (no ``passages`` list of passage records), fewer than :data:`MIN_PASSAGES`
identified passages, passages of more than one bridge (the ``bridge`` the run records name), a
spread of ``f1`` above :data:`F1_SPREAD_MAX` or of ``ζ1`` above :data:`ZETA_SPREAD_MAX` (spread =
(max - min) / median; both bounds are the project's choice: beyond them the passages are not one
bridge in one state, or the identification is not to be trusted).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from adm_sim.errors import InputError
from adm_sim.fields import core
from adm_sim.files import input_file, read_text
from adm_sim.model.bridge import Bridge

__all__ = ["F1_SPREAD_MAX", "MIN_PASSAGES", "MeasuredModes", "ZETA_QUANTILE", "ZETA_SPREAD_MAX", "apply_measured",
           "read_measured"]

#: Fewest identified passages a measured bridge is built from.
MIN_PASSAGES = 3
#: Quantile of the identified ζ1 taken as the bridge's damping (the lower quartile).
ZETA_QUANTILE = 0.25
#: Largest (max - min) / median of f1 and of ζ1 over the passages (project's choice).
F1_SPREAD_MAX = 0.05
ZETA_SPREAD_MAX = 1.0
#: Phases whose runs carry a damping that is not the bridge's own (an added Δζ).
DZ_PHASES = ("mlm_zeta_dz", "bracketing", "root_search")
#: Keys every passage record of the monitor's JSON has.
PASSAGE_KEYS = ("identified", "f1_hz", "zeta1_pct", "peak_acc_m_s2", "level")


@dataclass(frozen=True)
class MeasuredModes:
    """First mode of a bridge from the identified passages of a monitor's JSON (module docstring).

    ``f1_hz`` (median) and ``zeta1_pct`` (``ZETA_QUANTILE`` quantile) are what the bridge gets;
    ``f1_all_hz``, ``zeta1_all_pct`` the values of the ``n_used`` passages used, ``n_passages`` the
    file's passages, ``n_excluded_dz`` those left out for an added Δζ, ``path`` the file.
    """

    path: str
    f1_hz: float
    zeta1_pct: float
    f1_all_hz: tuple
    zeta1_all_pct: tuple
    n_passages: int
    n_excluded_dz: int
    bridge: str | None

    @property
    def n_used(self):
        return len(self.f1_all_hz)

    @property
    def zeta1_median_pct(self):
        return float(np.median(self.zeta1_all_pct))

    @property
    def f1_spread(self):
        return _spread(self.f1_all_hz)

    @property
    def zeta1_spread(self):
        return _spread(self.zeta1_all_pct)

    def to_dict(self):
        return {"file": self.path, "measured": ["n0_hz", "zeta_pct", "EJ_Nm2"], "n_passages_used": self.n_used,
                "n_passages_in_file": self.n_passages, "n_passages_excluded_dz": self.n_excluded_dz,
                "n0_hz": self.f1_hz, "n0_rule": "median of f1",
                "f1_min_hz": min(self.f1_all_hz), "f1_max_hz": max(self.f1_all_hz), "f1_spread": self.f1_spread,
                "f1_spread_max": F1_SPREAD_MAX,
                "zeta_pct": self.zeta1_pct, "zeta_rule": f"{100 * ZETA_QUANTILE:g} % quantile of zeta1 (project's choice)",
                "zeta1_median_pct": self.zeta1_median_pct, "zeta1_min_pct": min(self.zeta1_all_pct),
                "zeta1_max_pct": max(self.zeta1_all_pct), "zeta1_spread": self.zeta1_spread,
                "zeta1_spread_max": ZETA_SPREAD_MAX, "EJ_rule": "Eq. (18) from the measured n0 and the given mu"}

    def lines(self, design=None, measured=None):
        """Text lines: which values were measured, over how many passages, their spread; with the
        ``design`` and ``measured`` bridges, what each replaced."""
        out = [f"measured bridge from {self.path}: {self.n_used} identified passages"
               + (f" of {self.n_passages}" if self.n_passages != self.n_used else "")
               + (f" ({self.n_excluded_dz} runs with an added dz left out)" if self.n_excluded_dz else ""),
               f"  n0   = {self.f1_hz:.4f} Hz, median of f1 ({min(self.f1_all_hz):.4f} .. {max(self.f1_all_hz):.4f} Hz, "
               f"spread {100 * self.f1_spread:.2f} %)" + (f"; given {design.n0_hz:.4f} Hz" if design else ""),
               f"  zeta = {self.zeta1_pct:.3f} %, {100 * ZETA_QUANTILE:g} % quantile of zeta1 (project's choice; median "
               f"{self.zeta1_median_pct:.3f} %, {min(self.zeta1_all_pct):.3f} .. {max(self.zeta1_all_pct):.3f} %, spread "
               f"{100 * self.zeta1_spread:.1f} %)" + (f"; given {100 * design.damping_ratio:.3g} %" if design else "")]
        if design is not None and measured is not None:
            out.append(f"  EJ   = {measured.EJ_Nm2:.5g} N m^2 from n0 and mu = {measured.mass_per_length_kg_m:.6g} kg/m "
                       f"(Eq. (18); given {design.EJ_Nm2:.5g} N m^2); span, mu and the rest as given")
        return out


def _spread(values):
    v = np.asarray(values, dtype=float)
    return float((v.max() - v.min()) / np.median(v))


def _finite_positive(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def read_measured(text, option="--measured"):
    """:class:`MeasuredModes` of a monitor's JSON file ``text`` (module docstring); one line when refused."""
    path = input_file(text, option, "monitor JSON file (monitor.py --json)")
    where = f"{option}: {str(text)!r}"
    raw = read_text(path, option)
    try:
        doc = json.loads(raw)
    except json.JSONDecodeError as exc:
        raise InputError(f"{where} is not JSON ({exc.msg} at line {exc.lineno} column {exc.colno}); give the file "
                         f"monitor.py --json wrote") from None
    passages = doc.get("passages") if isinstance(doc, dict) else None
    if not isinstance(passages, list) or not all(isinstance(p, dict) for p in passages):
        raise InputError(f"{where} is not the monitor's JSON: no 'passages' list; give the file monitor.py --json wrote")
    for k, p in enumerate(passages, start=1):
        missing = [key for key in PASSAGE_KEYS if key not in p]
        if missing:
            raise InputError(f"{where} is not the monitor's JSON: passage {k} has no {', '.join(map(repr, missing))}; "
                             f"give the file monitor.py --json wrote")
    ident = [p for p in passages if p["identified"] is True and _finite_positive(p["f1_hz"])
             and _finite_positive(p["zeta1_pct"])]
    used = [p for p in ident if p.get("phase") not in DZ_PHASES]
    n_dz = len(ident) - len(used)
    bridges = sorted({str(p["bridge"]) for p in used if p.get("bridge")})
    if len(bridges) > 1:
        raise InputError(f"{where} mixes the passages of bridges {', '.join(bridges)}; give the passages of one bridge")
    if len(used) < MIN_PASSAGES:
        raise InputError(f"{where} has {len(used)} identified passage(s) of {len(passages)}"
                         + (f" ({n_dz} with an added dz left out)" if n_dz else "")
                         + f"; at least {MIN_PASSAGES} are needed for a measured n0 and zeta")
    f1 = tuple(float(p["f1_hz"]) for p in used)
    z = tuple(float(p["zeta1_pct"]) for p in used)
    for name, vals, bound in (("f1", f1, F1_SPREAD_MAX), ("zeta1", z, ZETA_SPREAD_MAX)):
        if _spread(vals) > bound:
            raise InputError(f"{where}: the identified {name} spread by {100 * _spread(vals):.3g} % ((max - min) / "
                             f"median, {min(vals):.4g} .. {max(vals):.4g}); allowed at most {100 * bound:g} % (the "
                             f"project's bound: the passages are not one bridge in one state)")
    zq = float(np.quantile(np.asarray(z), ZETA_QUANTILE))
    return MeasuredModes(path=str(text), f1_hz=float(np.median(f1)), zeta1_pct=min(zq, float(np.median(z))),
                         f1_all_hz=f1, zeta1_all_pct=z, n_passages=len(passages), n_excluded_dz=n_dz,
                         bridge=bridges[0] if bridges else None)


def apply_measured(text, bridge, option="--measured"):
    """``(measured bridge, MeasuredModes)``: ``bridge`` with n0 and ζ from the monitor's JSON
    ``text`` and EJ from n0 and its μ (Eq. (18), :meth:`adm_sim.model.bridge.Bridge.from_frequency`)."""
    m = read_measured(text, option)
    try:
        core("n0_hz").check(m.f1_hz)  # the registry's ranges; the model checks only its invariants
        core("damping_ratio").check(m.zeta1_pct / 100.0)
        measured = Bridge.from_frequency(bridge.span_m, m.f1_hz, bridge.mass_per_length_kg_m, m.zeta1_pct / 100.0,
                                         n_modes=bridge.n_modes, damping_model=bridge.damping_model,
                                         name=f"{bridge.name or 'bridge'} (measured)", bridge_type=bridge.bridge_type)
    except InputError as exc:
        raise InputError(f"{option}: {str(text)!r} gives {exc}") from None
    return measured, m


# ---------------------------------------------------------------------- command-line hooks
MEASURED_HELP = ("the monitor's JSON (monitor.py --json): n0 = median f1 and zeta = lower quartile of zeta1 of "
                 "its identified passages (at least 3), EJ from n0 and the given mu (Eq. 18); the rest of the "
                 "bridge as given")


def add_measured_argument(parser):
    """``--measured PASSAGES.json`` on a command's parser."""
    parser.add_argument("--measured", default=None, metavar="PASSAGES.json", help=MEASURED_HELP)


def measured_bridge(args, bridge):
    """``(bridge, MeasuredModes or None)``: with ``args.measured`` the measured bridge (printed as
    lines on stdout: what was measured, over how many passages, the spread), else ``bridge``."""
    text = getattr(args, "measured", None)
    if text is None:
        return bridge, None
    measured, m = apply_measured(text, bridge)
    print("\n".join(m.lines(bridge, measured)), flush=True)
    return measured, m
