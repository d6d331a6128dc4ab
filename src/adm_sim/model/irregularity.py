"""Vertical track irregularity under the wheels of the DIM: spectra, random profiles, defects.

The spec strings and profile files the user gives are read by :mod:`adm_sim.inputs.track_profile`.

The paper's DIM (Section 2) rolls every wheel on a perfectly smooth rail: the primary suspension
of axle ``i`` sees the rail displacement ``w_i`` and velocity ``w_dot_i`` of Eq. (9). On a rough
track the wheel follows rail *plus* irregularity; Eq. (9) gains the profile's terms

    w_i      = sum_j phi_j(x_i) q_j                  + r(x_i)
    w_dot_i  = sum_j phi_j(x_i) q_dot_j + v (sum_j phi_j'(x_i) q_j + r'(x_i))

(``r`` the profile's displacement of the rail top at the wheel, m, positive *downwards* like the
deck deflection ``w`` (z down, Section 2); ``v r'`` the vertical velocity the profile imposes on a
wheel moving at speed ``v``). The MLM carries no wheel and is unaffected.

Sign. Inputs are elevations (up): a measured file's ``elevation_m``, a ramp's ``height`` (rising
by ``height`` m) and a joint's ``depth`` (a dip). They enter as ``r = -elevation``, so a 10 mm ramp
lifts the wheel by 10 mm (VBI-2D's verification case with the 10 mm ramp, ``tests/model/test_vehicles.py``).
A random profile is symmetric in distribution; its ``r`` is the harmonic sum as generated.

Where the profile lives. The model of the paper has a rigid, smooth track off the bridge (a unit
rests until its first axle enters, :class:`adm_sim.integrate.rk4_sides.TrainSide`); here the profile is
defined on the deck, ``x`` in ``[0, L]`` measured from the left support, and is zero off it. A
random profile is pinned to zero at both supports (its linear trend over the deck is removed),
so a wheel meets no step on entering or leaving; a measured profile is used as given (zero outside
the file's positions). The vehicles therefore enter the bridge at rest, as in the smooth model.

Spectra (one-sided PSD ``S(Omega)`` in m^2/(rad/m), ``Omega`` the spatial angular frequency in
rad/m, variance ``int_0^inf S dOmega``):

* German low / high disturbance (vertical profile, the spectra of the train-track-bridge
  literature): ``S = A_v Omega_c^2 / ((Omega^2 + Omega_r^2)(Omega^2 + Omega_c^2))``;
* FRA classes 1..6 (US Federal Railroad Administration, vertical profile):
  ``S = k A_v Omega_c^2 / (Omega^2 (Omega^2 + Omega_c^2))``, ``k = 0.25``;
* ISO 8608 classes A..H (road surface profiles, the form VBI codes use for a rough deck surface):
  ``G_d(n) = G_d(n0) (n / n0)^-w`` in m^3 (m^2/(cycle/m)), ``n0 = 0.1`` cycle/m, waviness
  ``w = 2``; here ``S(Omega) = G_d(Omega / 2 pi) / (2 pi)`` (same variance).

The coefficients are in :data:`SPECTRA` (one table, easy to swap) with their sources; see
``docs/irregularities.md`` for the item-by-item comparison of two independent public
implementations.

Random profiles: the spectral representation (sum of harmonics with independent uniform random
phases, ``a_k = sqrt(2 S(Omega_k) dOmega)``), ``Omega_k`` the midpoints of equal bins over the
wavelength band; the seed fixes the phases. The profile's Welch PSD averaged over seeds matches
``S`` within 15 % over the band (``tests/model/test_irregularity.py``).

Discrete defects: a ramp (linear rise ``height_m`` over ``length_m`` from ``at_m``, then level)
and a joint (a cosine dip of depth ``depth_m`` and length ``length_m`` centred at ``at_m``).

A profile is evaluated through a cubic spline of its samples (:class:`Profile`), which gives
``r`` and ``r'`` at any position bit for bit alike for the numpy stepper, the compiled kernels
and the ROS train node.

What the model can represent (:func:`check_bounds`, every profile at every entry: the CLI, the
study, the train node's parameters). The wheel is a point on the rail that follows ``r(x)`` at
the constant horizontal speed ``v``; the profile is refused beyond

* slope ``|r'| <=`` :data:`MAX_SLOPE` = 0.05 (the project's choice: small-slope kinematics, the
  wheel's path along the rail is longer than ``x`` by ``r'^2 / 2 <= 0.125 %``, which the model
  ignores);
* curvature ``|r''| <=`` :data:`MAX_CURVATURE_1_M` = 1 / 0.46 m (the project's choice: a wheel of
  0.46 m tread radius, a high-speed wheelset's nominal size, cannot follow a dip tighter than its
  own tread, and a point contact does not see the bump it rides over);
* a profile's shortest wave against the space step ``ds`` of a run (:func:`check_step`): twice the
  shortest distance between its turning points (the samples' local extrema, swings below
  :data:`MIN_SWING_M` = 0.1 mm ignored, the project's choice) at least
  :data:`MIN_STEPS_PER_WAVELENGTH` = 2 steps, so the RK4 stage points (half steps) sample every
  wave at least 4 times, twice the Nyquist rate. A ramp or a single dip has no such wave; a saw-tooth shorter than the
  step has.

Within these bounds a profile may still be severe enough to lift a wheel off the rail, which the
DIM reports (:mod:`adm_sim.integrate.contact`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from adm_sim.errors import InputError


@dataclass(frozen=True)
class Spectrum:
    """A vertical-profile PSD of one standard and class.

    ``kind`` ``"german"``: ``A_v Omega_c^2 / ((Omega^2 + Omega_r^2)(Omega^2 + Omega_c^2))``;
    ``"fra"``: ``k A_v Omega_c^2 / (Omega^2 (Omega^2 + Omega_c^2))``. ``A_v`` in m^2 rad/m (m rad
    for the German form, whose S is m^2/(rad/m) as well), ``Omega`` in rad/m. ``"iso"`` (ISO 8608):
    ``G_d(n0) (n / n0)^-w / (2 pi)`` with ``n = Omega / 2 pi``, ``a_v = G_d(n0)`` in m^3,
    ``n0_cyc_m`` in cycle/m, ``waviness`` ``w``. ``band_m`` the wavelength range (m) the standard
    defines the spectrum over.
    """

    name: str
    kind: str
    a_v: float
    omega_c: float
    omega_r: float = 0.0
    k: float = 1.0
    band_m: tuple = (1.0, 80.0)
    source: str = ""
    n0_cyc_m: float = 0.1
    waviness: float = 2.0

    def psd(self, omega):
        """One-sided PSD (m^2/(rad/m)) at spatial angular frequency ``omega`` (rad/m)."""
        w2 = np.asarray(omega, dtype=float) ** 2
        oc2 = self.omega_c ** 2
        if self.kind == "german":
            return self.a_v * oc2 / ((w2 + self.omega_r ** 2) * (w2 + oc2))
        if self.kind == "iso":
            n = np.sqrt(w2) / (2.0 * np.pi)
            return self.a_v * (n / self.n0_cyc_m) ** (-self.waviness) / (2.0 * np.pi)
        return self.k * self.a_v * oc2 / (w2 * (w2 + oc2))


_GERMAN_SRC = ("German high-speed track spectra (vertical profile), as tabulated in the train-track-bridge "
               "literature (e.g. Zhai, Vehicle-Track Coupled Dynamics; Guo, Xia, De Roeck, Liu, Comput. Struct. "
               "112-113 (2012) 205-216)")
_FRA_SRC = ("FRA track classes (vertical profile), k = 0.25, A_v in cm^2 rad/m converted to m^2 rad/m "
            "(Fryba, Dynamics of Railway Bridges, 1996; Berawi, PhD thesis, Porto; as in TTB-2D, "
            "github.com/DanielCanteroNTNU/TTB-2D A04_Options.m, Cantero, SoftwareX 20 (2022) 101253)")

_ISO_SRC = ("ISO 8608 (Mechanical vibration - Road surface profiles - Reporting of measured data), classes A..H "
            "by G_d(n0) at n0 = 0.1 cycle/m, w = 2: the geometric mean of each class's limits; limits "
            "2^(3:2:17) 1e-6 m^3 as in VBI-2D, github.com/DanielCanteroNTNU/VBI-2D "
            "Functions/B07_OptionsProcessing.m and B21_ISO_Profile.m, D. Cantero, NTNU); band "
            "0.01..10 cycle/m, the standard's notes on the lower and upper spatial-frequency limits for on-road use")

#: FRA A_v per class, cm^2 rad/m (class 1 poorest .. class 6 best).
FRA_AV_CM2 = {1: 1.2107, 2: 1.0181, 3: 0.6816, 4: 0.5376, 5: 0.2095, 6: 0.0339}

#: ISO 8608 class limits of G_d(n0), 1e-6 m^3: lower limit of A, A/B, ..., G/H (H has no upper limit;
#: its geometric mean continues the factor 4 of the others).
ISO_LIMITS_UM3 = (8.0, 32.0, 128.0, 512.0, 2048.0, 8192.0, 32768.0, 131072.0)
#: ISO 8608 G_d(n0) per class, 1e-6 m^3 (geometric mean of the class limits: 16, 64, ..., 262144).
ISO_GD_UM3 = {c: 16.0 * 4.0 ** i for i, c in enumerate("abcdefgh")}

#: Every spectrum by name: the one place the coefficients live.
SPECTRA = {
    "german-low": Spectrum("german-low", "german", a_v=4.032e-7, omega_c=0.8246, omega_r=0.0206,
                           band_m=(0.5, 80.0), source=_GERMAN_SRC),
    "german-high": Spectrum("german-high", "german", a_v=1.080e-6, omega_c=0.8246, omega_r=0.0206,
                            band_m=(0.5, 80.0), source=_GERMAN_SRC),
    **{f"fra-{c}": Spectrum(f"fra-{c}", "fra", a_v=av * 1e-4, omega_c=0.8245, k=0.25,
                            band_m=(1.524, 304.8), source=_FRA_SRC) for c, av in FRA_AV_CM2.items()},
    **{f"iso-{c}": Spectrum(f"iso-{c}", "iso", a_v=gd * 1e-6, omega_c=0.0, band_m=(0.1, 100.0),
                            source=_ISO_SRC, n0_cyc_m=0.1, waviness=2.0) for c, gd in ISO_GD_UM3.items()},
}

#: Default wavelength band of a generated profile (m): within every spectrum's own band; the
#: wavelengths that matter for a deck of 4..40 m and the wheelsets at 160..350 km/h.
DEFAULT_BAND_M = (2.0, 80.0)


def refusal(key, value, allowed):
    """The one-line refusal of an irregularity option ``key`` of value ``value``."""
    return InputError(f"irregularity: {key} = {value!r} is not allowed; allowed {allowed}")


def spectrum(name):
    """The :class:`Spectrum` called ``name`` (``german-low``, ``german-high``, ``fra-1`` .. ``fra-6``,
    ``iso-a`` .. ``iso-h``)."""
    s = SPECTRA.get(str(name).strip().lower())
    if s is None:
        raise refusal("spectrum", name, ", ".join(SPECTRA))
    return s


def check_band(spec, band_m):
    """The wavelength band ``(lo, hi)`` (m) if inside what ``spec`` defines, else InputError."""
    lo, hi = (float(b) for b in band_m)
    blo, bhi = spec.band_m
    if not (math.isfinite(lo) and math.isfinite(hi)) or not (blo <= lo < hi <= bhi):
        raise InputError(f"irregularity: band = {lo:g}:{hi:g} m is outside the {spec.name} spectrum; "
                         f"allowed lo < hi within [{blo:g}, {bhi:g}] m")
    return lo, hi


# ---------------------------------------------------------------------- profiles
@dataclass(frozen=True, eq=False)
class Profile:
    """A profile ``r(x)`` (m, the rail top's displacement *downwards*, the sign of the deck
    deflection: ``r = -elevation``) sampled at increasing positions ``x_m`` (m from the left
    support); zero outside ``[x_m[0], x_m[-1]]``. ``description`` names how it was made (a spec
    that rebuilds it)."""

    x_m: np.ndarray
    r_m: np.ndarray
    description: str = ""
    _spline: object = field(default=None, repr=False)

    def __post_init__(self):
        x = np.asarray(self.x_m, dtype=float)
        r = np.asarray(self.r_m, dtype=float)
        check_samples(x, r, "profile")
        from scipy.interpolate import CubicSpline  # noqa: PLC0415  scipy.interpolate only when a profile is used

        object.__setattr__(self, "x_m", x)
        object.__setattr__(self, "r_m", r)
        object.__setattr__(self, "_spline", CubicSpline(x, r, bc_type="not-a-knot"))

    def __repr__(self):
        return f"Profile({self.description or 'samples'}, {self.x_m.size} points, x {self.x_m[0]:g}..{self.x_m[-1]:g} m)"

    def evaluate(self, x_m, curvature=False):
        """``(r, r')`` at positions ``x_m`` (any shape): downward displacement (m) and its slope (-), 0 outside;
        with ``curvature`` also ``r''`` (1/m)."""
        x = np.asarray(x_m, dtype=float)
        inside = (x >= self.x_m[0]) & (x <= self.x_m[-1])
        r = np.zeros(x.shape)
        s = np.zeros(x.shape)
        c = np.zeros(x.shape)
        if np.any(inside):
            xi = x[inside]
            r[inside] = self._spline(xi)
            s[inside] = self._spline(xi, 1)
            if curvature:
                c[inside] = self._spline(xi, 2)
        return (r, s, c) if curvature else (r, s)

    def rms_m(self):
        return float(np.sqrt(np.mean(self.r_m ** 2)))


#: Largest |slope| of a profile (-), the project's choice (module docstring).
MAX_SLOPE = 0.05
#: Largest |curvature| of a profile (1/m): 1 / (0.46 m tread radius), the project's choice.
MAX_CURVATURE_1_M = 1.0 / 0.46
#: Fewest space steps per shortest profile wave (:func:`check_step`), the project's choice.
MIN_STEPS_PER_WAVELENGTH = 2.0
#: Smallest swing (m) that makes a turning point of a profile (:func:`shortest_wavelength_m`).
MIN_SWING_M = 1e-4


def profile_extremes(profile):
    """``(max |r'|, x at it, max |r''|, x at it)`` of ``profile``'s spline over its samples and
    the midpoints between them (m, -, 1/m)."""
    x = profile.x_m
    xe = np.empty(2 * x.size - 1)
    xe[0::2] = x
    xe[1::2] = 0.5 * (x[1:] + x[:-1])
    s = np.abs(profile._spline(xe, 1))
    c = np.abs(profile._spline(xe, 2))
    i, j = int(np.argmax(s)), int(np.argmax(c))
    return float(s[i]), float(xe[i]), float(c[j]), float(xe[j])


def check_bounds(profile, what="irregularity"):
    """Refuse a profile the model cannot represent: |slope| > :data:`MAX_SLOPE` or |curvature| >
    :data:`MAX_CURVATURE_1_M` anywhere (one-line InputError naming the value and where); returns it."""
    smax, xs, cmax, xc = profile_extremes(profile)
    if smax > MAX_SLOPE:
        raise InputError(f"{what}: {profile.description or 'profile'} has slope {smax:.3g} (-) at x = {xs:.4g} m; "
                         f"allowed |slope| <= {MAX_SLOPE:g} (the project's small-slope bound: the DIM's wheel "
                         f"follows the rail at constant speed)")
    if cmax > MAX_CURVATURE_1_M:
        raise InputError(f"{what}: {profile.description or 'profile'} has curvature {cmax:.3g} 1/m at x = {xc:.4g} m; "
                         f"allowed |curvature| <= {MAX_CURVATURE_1_M:.3g} 1/m (the project's bound: a 0.46 m wheel "
                         f"tread follows no tighter dip)")
    return profile


def shortest_wavelength_m(profile):
    """Twice the shortest distance (m) between the profile's turning points: the local extrema of
    its samples, each kept only when it differs from the last kept one by at least
    :data:`MIN_SWING_M` (a hysteresis filter: measurement noise is no wave); ``inf`` with fewer
    than three turning points (a ramp, a single dip)."""
    x, r = profile.x_m, profile.r_m
    d = np.diff(r)
    turn = np.flatnonzero(d[1:] * d[:-1] < 0.0) + 1  # strict local extrema of the samples
    kept = [0]
    for i in turn.tolist() + [r.size - 1]:
        if abs(r[i] - r[kept[-1]]) >= MIN_SWING_M:
            if len(kept) > 1 and (r[i] - r[kept[-1]]) * (r[kept[-1]] - r[kept[-2]]) > 0.0:
                kept[-1] = i  # the same direction goes on: move the turning point
            else:
                kept.append(i)
    if len(kept) < 4:  # start, end and at most one turning point between
        return math.inf
    return 2.0 * float(np.min(np.diff(x[kept[1:-1]])))


def check_step(profile, ds_m, what="irregularity"):
    """Refuse a profile whose shortest wave (:func:`shortest_wavelength_m`) spans fewer than
    :data:`MIN_STEPS_PER_WAVELENGTH` space steps ``ds_m`` of a run (one-line InputError)."""
    if profile is None:
        return
    lam = shortest_wavelength_m(profile)
    if lam < MIN_STEPS_PER_WAVELENGTH * ds_m:
        raise InputError(f"{what}: {profile.description or 'profile'} has a wave of {lam:.3g} m (twice the "
                         f"distance of two turning points), {lam / ds_m:.3g} space steps of ds = {ds_m:.3g} m; "
                         f"allowed >= {MIN_STEPS_PER_WAVELENGTH:g} steps per wave (the project's bound: a smoother "
                         f"profile, or more steps_per_period)")


def check_samples(x, r, what):
    """Refuse profile samples that are not two increasing, finite columns within 0.1 m."""
    if x.ndim != 1 or r.shape != x.shape or x.size < 4:
        raise InputError(f"{what}: positions and elevations must be two columns of equal length >= 4; "
                         f"got {x.size} and {r.size}")
    bad = np.flatnonzero(~np.isfinite(x) | ~np.isfinite(r))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{what}: row {i + 1} has position {float(x[i])!r} m, elevation {float(r[i])!r} m; "
                         f"allowed finite numbers (no NaN or inf)")
    step = np.diff(x)
    if np.any(step <= 0.0):
        i = int(np.flatnonzero(step <= 0.0)[0])
        raise InputError(f"{what}: position_m = {x[i + 1]:g} m at row {i + 2} does not increase "
                         f"(previous {x[i]:g} m); allowed strictly increasing positions")
    if np.max(np.abs(r)) > 0.1:
        raise InputError(f"{what}: elevation_m = {np.max(np.abs(r)):g} m; allowed |elevation| <= 0.1 m")


def harmonic_sum(spec, band_m, seed, x_m, n_harmonics=None, length_m=None):
    """A random profile of ``spec`` at positions ``x_m`` (m): sum of harmonics with random phases.

    ``Omega_k`` are the midpoints of ``n_harmonics`` equal bins of ``[2 pi / hi, 2 pi / lo]``
    (``band_m = (lo, hi)``), amplitudes ``sqrt(2 S(Omega_k) dOmega)``, phases uniform on
    ``[0, 2 pi)`` from ``numpy.random.default_rng(seed)``. Default ``n_harmonics``: a bin width of
    ``2 pi / length_m`` (one period of the profile covers ``length_m``, default 2000 m).

    Returns ``r`` (m), shape of ``x_m``.
    """
    lo, hi = check_band(spec, band_m)
    w0, w1 = 2.0 * np.pi / hi, 2.0 * np.pi / lo
    if n_harmonics is None:
        n_harmonics = int(math.ceil((w1 - w0) / (2.0 * np.pi / (length_m or 2000.0))))
    dw = (w1 - w0) / n_harmonics
    w = w0 + dw * (np.arange(n_harmonics) + 0.5)
    amp = np.sqrt(2.0 * spec.psd(w) * dw)
    phase = np.random.default_rng(int(seed)).uniform(0.0, 2.0 * np.pi, n_harmonics)
    x = np.asarray(x_m, dtype=float)
    out = np.zeros(x.size)
    for i in range(0, x.size, 4096):  # bounded memory: (chunk, n_harmonics)
        xc = x.ravel()[i:i + 4096]
        out[i:i + xc.size] = np.cos(np.outer(xc, w) + phase) @ amp
    return out.reshape(x.shape)


def random_profile(spec_name, seed, length_m, band_m=DEFAULT_BAND_M, dx_m=None):
    """A random profile of spectrum ``spec_name`` over the deck ``[0, length_m]``, pinned to zero
    at both ends (linear trend removed; see the module docstring), sampled every ``dx_m``
    (default: a 20th of the shortest wavelength, at most 0.05 m)."""
    spec = spectrum(spec_name)
    lo, hi = check_band(spec, band_m)
    dx = min(0.05, lo / 20.0) if dx_m is None else float(dx_m)
    n = max(int(math.ceil(length_m / dx)), 4)
    x = np.linspace(0.0, float(length_m), n + 1)
    r = harmonic_sum(spec, (lo, hi), seed, x)
    r = r - (r[0] + (r[-1] - r[0]) * x / x[-1])
    return Profile(x, r, description=f"{spec.name}:seed={int(seed)}:band={lo:g}:{hi:g}")


def ramp(x_m, at_m, length_m, height_m):
    """A ramp's elevation: 0 before ``at_m``, linear to ``height_m`` over ``length_m``, then
    ``height_m`` (m, up; it enters a profile as ``r = -ramp``)."""
    x = np.asarray(x_m, dtype=float)
    return height_m * np.clip((x - at_m) / length_m, 0.0, 1.0)


def joint(x_m, at_m, length_m, depth_m):
    """A joint's elevation: a cosine dip of depth ``depth_m`` (m) and length ``length_m`` centred at
    ``at_m`` (negative: it enters a profile as ``r = -joint``, a downward displacement)."""
    x = np.asarray(x_m, dtype=float)
    u = (x - at_m) / length_m + 0.5
    inside = (u > 0.0) & (u < 1.0)
    return np.where(inside, -0.5 * depth_m * (1.0 - np.cos(2.0 * np.pi * np.clip(u, 0.0, 1.0))), 0.0)


def welch_psd(r_m, dx_m, nperseg):
    """Welch PSD of a profile in the units of :class:`Spectrum`: ``(Omega (rad/m), S (m^2/(rad/m)))``."""
    from scipy.signal import welch  # noqa: PLC0415  only for PSD checks

    f, p = welch(np.asarray(r_m, dtype=float), fs=1.0 / dx_m, nperseg=nperseg, detrend="constant")
    return 2.0 * np.pi * f, p / (2.0 * np.pi)
