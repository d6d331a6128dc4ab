"""HSLM-A universal load trains of EN 1991-2, generated from their table, not typed out; HSLM-B built
from the N and d the user reads off the standard.

EN 1991-2:2003 6.4.6.1.1 defines the High Speed Load Model HSLM-A as ten universal trains
HSLM-A1 ... HSLM-A10 (Table 6.3: number of intermediate coaches N, coach length D, bogie axle
spacing d, point force P; layout in Fig. 6.12). Annex E (Table E.1) gives the limits of validity
of the model and the choice of the critical universal train. They are moving loads only (point
forces P), not vehicles: the Detailed Interaction Model cannot run them.

Layout (Fig. 6.12), front to rear, every axle carrying P:

* leading power car: 4 axles, spacings 3 m, 11 m, 3 m;
* leading end coach: a conventional bogie of wheelbase **d** whose first axle lies
  :data:`POWER_TO_END_COACH_M` (3.525 m) behind the last power-car axle; the coupling point
  between power car and end coach lies halfway across that gap (17 + 3.525 / 2 = 18.7625 m behind
  the first axle), and the centre of the first Jacobs bogie lies D behind the coupling point;
* N intermediate coaches of length D between Jacobs bogies (wheelbase d), i.e. N + 1 Jacobs
  bogies at spacing D;
* trailing end coach and power car mirroring the leading ones.

That is 4 + 2 + 2 (N + 1) + 2 + 4 = 2N + 14 axles, the regular spacing D that drives the
resonances ``v = n0 D / i``, and a first-to-last axle distance of 2 x 18.7625 + (N + 2) D =
375.5 .. 398.5 m, inside the 400 m of EN 1991-2 Annex E. The layout agrees to 1e-12 m on every
axle of A1 .. A10 with independent public implementations (Karoumi's ``HSLMA.m``, KTH; caldintav's
``a01 .. a10.def``, UPM; SincBridgeDynamics.jl ``A_1 .. A_10``); ``tests/model/test_hslm.py`` holds
that table as literals.

HSLM-B (EN 1991-2 6.4.6.1.1, for simply supported spans below 7 m): N point forces of 170 kN at a
uniform spacing d, N and d read off the standard's figure for the span. We found no public copy or
implementation of that figure to take N(L) and d(L) from or to test against, so adm-sim does not
choose them: the user gives them, ``HSLM-B:N=<n>:d=<m>`` (:func:`hslm_b_spec`), and the check uses
that train for spans below 7 m and refuses HSLM-A there.
"""

from __future__ import annotations

import math
import re

import numpy as np

from adm_sim.errors import InputError

#: EN 1991-2 Table 6.3: name -> (N intermediate coaches, D coach length m, d bogie axle spacing m, P kN).
HSLM_A_TABLE = {
    "HSLM-A1": (18, 18.0, 2.0, 170.0),
    "HSLM-A2": (17, 19.0, 3.5, 200.0),
    "HSLM-A3": (16, 20.0, 2.0, 180.0),
    "HSLM-A4": (15, 21.0, 3.0, 190.0),
    "HSLM-A5": (14, 22.0, 2.0, 170.0),
    "HSLM-A6": (13, 23.0, 2.0, 180.0),
    "HSLM-A7": (13, 24.0, 2.0, 190.0),
    "HSLM-A8": (12, 25.0, 2.5, 190.0),
    "HSLM-A9": (11, 26.0, 2.0, 210.0),
    "HSLM-A10": (11, 27.0, 2.0, 210.0),
}
HSLM_A_NAMES = tuple(HSLM_A_TABLE)

#: Power-car axle spacings (m), Fig. 6.12.
POWER_CAR_SPACINGS_M = (3.0, 11.0, 3.0)
#: Last power-car axle to first end-coach axle (m), Fig. 6.12.
POWER_TO_END_COACH_M = 3.525
#: Coupling point between power car and end coach, behind the first axle (m): halfway across the
#: power-car-to-end-coach gap, Fig. 6.12.
COUPLING_POINT_M = 17.0 + 0.5 * POWER_TO_END_COACH_M

_NAME_RE = re.compile(r"^hslm-?a(\d+)$")


def hslm_name(text):
    """Canonical ``HSLM-Ak`` for ``text`` (case, dashes and blanks ignored), or None if it is not
    an HSLM-A name. An HSLM-A number outside 1..10 raises :class:`InputError`."""
    key = re.sub(r"[\s_]", "", str(text)).lower()
    m = _NAME_RE.match(key)
    if m is None:
        return None
    name = f"HSLM-A{int(m.group(1))}"
    if name not in HSLM_A_TABLE:
        raise InputError(f"train: {text!r} is not an HSLM-A universal train; allowed HSLM-A1 .. HSLM-A10 "
                         f"(EN 1991-2 Table 6.3)", field="train")
    return name


def hslm_axles(name):
    """Axle offsets behind the first axle (m) and axle loads (N) of universal train ``name``.

    Returns
    -------
    offsets_m, loads_n : ndarray, shape (2N + 14,)
    """
    N, D, d, P_kN = HSLM_A_TABLE[name]
    power = np.concatenate([[0.0], np.cumsum(POWER_CAR_SPACINGS_M)])  # 0, 3, 14, 17
    first_end = power[-1] + POWER_TO_END_COACH_M
    end_bogie = np.array([first_end, first_end + d])  # the end coach's bogie has wheelbase d
    jacobs_centres = COUPLING_POINT_M + D * np.arange(1, N + 2)  # N + 1 Jacobs bogies
    jacobs = (jacobs_centres[:, None] + np.array([-0.5 * d, 0.5 * d])).ravel()
    front = np.concatenate([power, end_bogie])
    # the rear half mirrors the front half about the middle of the Jacobs bogies
    middle = 0.5 * (jacobs_centres[0] + jacobs_centres[-1])
    rear = (2.0 * middle - front)[::-1]
    offsets = np.concatenate([front, jacobs, rear])
    return offsets, np.full(offsets.shape, 1000.0 * P_kN)


def regular_coach_length_m(name):
    """Coach length D (m) of universal train ``name``: the regular spacing of its Jacobs bogies."""
    return HSLM_A_TABLE[hslm_name(name)][1]


#: HSLM-B: the point force of every axle (kN), EN 1991-2 6.4.6.1.1.
HSLM_B_FORCE_KN = 170.0
#: Input sanity limits of HSLM-B's N (forces) and d (m); not the standard's range, which the user's
#: figure gives: outside them a typing error is far more likely than a reading of the figure.
HSLM_B_N_RANGE = (2, 100)
HSLM_B_D_RANGE_M = (0.5, 30.0)
_B_RE = re.compile(r"^hslm-?b(?::(.*))?$")
_B_ITEM_RE = re.compile(r"^(n|d)=(.*)$")
#: How to write an HSLM-B train (shown in refusals).
HSLM_B_SYNTAX = "HSLM-B:N=<forces>:d=<spacing m>"


def hslm_b_spec(text):
    """``(N, d_m)`` of an HSLM-B train written ``HSLM-B:N=<n>:d=<m>`` (case and blanks ignored), or None
    if ``text`` is not an HSLM-B name. A malformed one raises :class:`InputError` (one line)."""
    key = re.sub(r"\s", "", str(text)).lower()
    m = _B_RE.match(key)
    if m is None:
        return None
    hint = (f"give {HSLM_B_SYNTAX}, N and d read off EN 1991-2's HSLM-B figure for the span (adm-sim does not "
            f"include that figure)")
    if not m.group(1):
        raise InputError(f"train: {text!r} gives no N and d; {hint}", field="train")
    items = {}
    for part in m.group(1).split(":"):
        mi = _B_ITEM_RE.match(part)
        if mi is None or mi.group(1) in items:
            raise InputError(f"train: {text!r}: {part!r} is not N=<forces> or d=<spacing m> (each once); {hint}", field="train")
        items[mi.group(1)] = mi.group(2)
    if set(items) != {"n", "d"}:
        raise InputError(f"train: {text!r} needs both N and d; {hint}", field="train")
    lo, hi = HSLM_B_N_RANGE
    try:
        n = float(items["n"])
    except ValueError:
        n = math.nan
    if not (math.isfinite(n) and n == int(n) and lo <= n <= hi):
        raise InputError(f"train: HSLM-B N = {items['n']!r} is not a whole number of forces in [{lo}, {hi}]; {hint}", field="train")
    dlo, dhi = HSLM_B_D_RANGE_M
    try:
        d = float(items["d"])
    except ValueError:
        raise InputError(f"train: HSLM-B d = {items['d']!r} is not a number; allowed [{dlo:g}, {dhi:g}] m; "
                         f"{hint}", field="train") from None
    if not (math.isfinite(d) and dlo <= d <= dhi):
        raise InputError(f"train: HSLM-B d = {d:g} m is out of range; allowed [{dlo:g}, {dhi:g}] m; {hint}", field="train")
    return int(n), d


def hslm_b_train_name(n_forces, spacing_m):
    """The canonical name of HSLM-B with ``n_forces`` forces at ``spacing_m``: ``HSLM-B:N=10:d=3.5``."""
    return f"HSLM-B:N={int(n_forces)}:d={spacing_m:g}"


def hslm_b_axles(n_forces, spacing_m):
    """Axle offsets behind the first force (m) and loads (N) of HSLM-B: ``n_forces`` forces of 170 kN
    at the uniform spacing ``spacing_m`` (EN 1991-2 6.4.6.1.1).

    Returns
    -------
    offsets_m, loads_n : ndarray, shape (n_forces,)
    """
    offsets = spacing_m * np.arange(int(n_forces), dtype=float)
    return offsets, np.full(offsets.shape, 1000.0 * HSLM_B_FORCE_KN)


def is_hslm_b_name(name):
    """True for a canonical HSLM-B name (:func:`hslm_b_train_name`)."""
    return str(name).startswith("HSLM-B:")


def regular_spacing_m(name):
    """The regular spacing of the loads of universal train ``name`` (m): D of HSLM-A, d of HSLM-B. Its
    resonances lie at ``v = n0 spacing / i``."""
    if is_hslm_b_name(name):
        return hslm_b_spec(name)[1]
    return regular_coach_length_m(name)
