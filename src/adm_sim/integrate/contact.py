"""The DIM checks its own assumption: every wheel stays on the rail.

The DIM of the paper (Section 2) ties each wheelset to the rail: its displacement is the rail's
(Eq. 9) and the wheel-rail contact force (Eq. 7)

    F_i = G_i - m_w,i w''_i,    G_i = F_static,i - F_k1,i - F_c1,i

(compression positive; ``F_static,i`` the static axle load, ``F_k1``, ``F_c1`` the primary spring
and damper forces, ``w''_i`` the wheel's acceleration, Eq. 9 with the profile's ``v^2 r''``) may
take any sign in the equations, but a real wheel cannot pull on the rail: where ``F_i < 0`` the
wheel would lift off and the model's results beyond that instant describe a vehicle that does
not exist. Every DIM run (the numpy stepper, the compiled kernels, the bridge node) therefore
computes ``F_i`` of every axle on the bridge at stage 0 of every step and keeps, per lane, the
smallest force and the first tension (step, axle, force): a run with a tension has the status
:data:`CONTACT_LOST`. Off the bridge the track is rigid and smooth and the units rest, so the
static load holds there.

Limiting case (``tests/integrate/test_contact.py``): at low speed on a smooth track ``F_i`` tends to the
static axle load ``F_static,i``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Status of a DIM run in which a contact force became tensile (a wheel would lift off).
CONTACT_LOST = "contact_lost"
#: Status of a run whose every contact force stayed compressive (or an MLM run: no wheels).
CONTACT_OK = "ok"


@dataclass(frozen=True, repr=False)
class ContactCheck:
    """The contact check of every lane of a DIM run (n_lanes,) each.

    Attributes
    ----------
    min_n : ndarray
        Smallest contact force of any axle on the bridge at stage 0 of the steps done (N,
        compression positive); ``inf`` when no axle was on the bridge.
    first_k, first_axle : ndarray of int
        Step and axle (0-based) of the lane's first tension; -1: none.
    first_n : ndarray
        The force at that step and axle (N, < 0), 0 where none.
    speeds_m_s, dt_s : ndarray
        The lane's speed (m/s) and time step (s), to name the speed and the time.
    """

    min_n: np.ndarray
    first_k: np.ndarray
    first_axle: np.ndarray
    first_n: np.ndarray
    speeds_m_s: np.ndarray
    dt_s: np.ndarray

    @property
    def lost(self):
        """True per lane where a contact force became tensile (n_lanes,)."""
        return np.asarray(self.first_k) >= 0

    @property
    def status(self):
        """:data:`CONTACT_LOST` when any lane lost contact, else :data:`CONTACT_OK`."""
        return CONTACT_LOST if bool(self.lost.any()) else CONTACT_OK

    def first(self):
        """The lowest speed that lost contact: ``{"speed_kmh", "time_s", "axle", "force_n"}``
        (``axle`` counted from 1, the leading axle) or ``None``."""
        lost = np.flatnonzero(self.lost)
        if lost.size == 0:
            return None
        i = int(lost[np.argmin(self.speeds_m_s[lost])])
        return {"speed_kmh": float(self.speeds_m_s[i] * 3.6), "time_s": float(self.first_k[i] * self.dt_s[i]),
                "axle": int(self.first_axle[i]) + 1, "force_n": float(self.first_n[i]),
                "n_lanes_lost": int(lost.size), "n_lanes": int(self.lost.size)}

    def message(self, what="DIM"):
        """One line naming the first loss of contact, or ``None``."""
        fl = self.first()
        if fl is None:
            return None
        return (f"{what}: contact lost: the wheel of axle {fl['axle']} would lift off the rail at "
                f"{fl['speed_kmh']:.6g} km/h, t = {fl['time_s']:.4g} s (contact force {fl['force_n'] / 1e3:.4g} kN "
                f"< 0; {fl['n_lanes_lost']} of {fl['n_lanes']} speeds lost contact); the DIM assumes every wheel "
                f"stays on the rail, so its results there are not valid")

    def losses(self):
        """Every lane that lost contact, in lane order: ``{"lane", "speed_kmh", "time_s", "axle", "force_n"}``
        (``axle`` counted from 1)."""
        return [{"lane": int(i), "speed_kmh": float(self.speeds_m_s[i] * 3.6),
                 "time_s": float(self.first_k[i] * self.dt_s[i]), "axle": int(self.first_axle[i]) + 1,
                 "force_n": float(self.first_n[i])} for i in np.flatnonzero(self.lost)]

    def to_dict(self):
        """The JSON form: status, the first loss (or null), every lane's loss and the smallest force
        per lane (N)."""
        m = np.asarray(self.min_n, dtype=float)
        return {"status": self.status, "first_loss": self.first(), "losses": self.losses(),
                "min_contact_force_n": [None if not np.isfinite(x) else float(x) for x in m]}


class ContactTracker:
    """The numpy stepper's half of the check: fold the contact forces of a step into the lanes.

    Mirrors :func:`adm_sim.integrate.kernels.contact_forces` (same forces, same first tension per lane).
    """

    def __init__(self, grid):
        n = grid.n_lanes
        self.speeds_m_s = np.asarray(grid.speeds_m_s, dtype=float)
        self.dt_s = np.broadcast_to(np.asarray(grid.dt_s, dtype=float), (n,)).copy()
        self.min_n = np.full(n, np.inf)
        self.first_k = np.full(n, -1, dtype=np.int64)
        self.first_axle = np.full(n, -1, dtype=np.int64)
        self.first_n = np.zeros(n)

    def take(self, k, idx, force_n):
        """Contact forces ``force_n`` (n_lanes, n_on) of axles ``idx`` (n_on,) at stage 0 of step ``k``."""
        if len(idx) == 0:
            return
        np.minimum(self.min_n, force_n.min(axis=1), out=self.min_n)
        neg = force_n < 0.0
        if not neg.any():
            return
        for b in np.flatnonzero(neg.any(axis=1) & (self.first_k < 0)):
            j = int(np.flatnonzero(neg[b])[0])  # the first axle in the kernels' entry order
            self.first_k[b], self.first_axle[b], self.first_n[b] = k, int(idx[j]), force_n[b, j]

    def check(self):
        return ContactCheck(self.min_n.copy(), self.first_k.copy(), self.first_axle.copy(), self.first_n.copy(),
                            self.speeds_m_s, self.dt_s)
