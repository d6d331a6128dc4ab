"""HSLM-A universal load trains of EN 1991-2, generated from their table, not typed out.

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
``a01 .. a10.def``, UPM; SincBridgeDynamics.jl ``A_1 .. A_10``); ``tests/test_hslm.py`` holds
that table as literals.
"""

from __future__ import annotations

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
                         f"(EN 1991-2 Table 6.3)")
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
