"""Study cases: the (bridge, train) pairs of the field (paper Section 3.3) and the study settings.

A case carries its identity as fields (train, span, frequency index, mass function) next to its
:class:`adm_sim.model.bridge.Bridge`; nothing is parsed back out of bridge names.
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from adm_sim.model.bridge import Bridge, parametric_field
from adm_sim.errors import InputError
from adm_sim.fields import check_range
from adm_sim.limits import DEFAULT_SPEEDS
from adm_sim.model.parametric import FIELD_SPANS_M, MASS_FUNCTIONS
from adm_sim.integrate.step_grid import StepOptions
from adm_sim.inputs.speeds import parse_speeds
from adm_sim.inputs.track_profile import parse_irregularity
from adm_sim.inputs.train_files import load_train

from adm_calib.calibration_options import XTOL_STUDY, CalibrationOptions
from adm_calib.lower_bound import FIT_RANGE_MAX_HZ, LOWER_LIMIT_HZ  # noqa: F401  (re-exported for the study package)
from adm_calib.reference import STUDY_TRAINS, canonical_train_name

#: Frequency indices of the field: 1 = LB power law ... 5 = UB power law (Section 3.1.1).
FREQ_INDICES = (1, 2, 3, 4, 5)
#: Speed resolution of the refined mode (``--refine-speed``), km/h.
REFINED_SPEED_STEP_KMH = 0.05
#: Spans of the field (m).
SPAN_RANGE_M = (4, 40)
#: Span layouts of a study (``--spans-layout``): 1 = the paper's simply supported spans; N = a
#: continuous deck of N equal spans of the case's span (:func:`deck_case_bridge`).
SPANS_LAYOUTS = (1, 2, 3, 4, 5, 6)
#: Modes of a deck case per span: the deck's first three clusters of N modes (N equal spans), the
#: counterparts of the three modes the paper keeps on a simply supported span (Section 2.3).
DECK_MODES_PER_SPAN = 3
#: Shipped variants of the study trains, studied like their paper train and compared with its
#: Table B (variant -> paper train): ``Eurostar-table`` is Table A1's PC 2-8 column as printed.
TRAIN_VARIANTS = {"Eurostar-table": "Eurostar"}
#: Mass functions of Table 1.
MASS_FUNCTION_NAMES = ("mu1", "mu2", "mu3", "mu4", "mu5", "mu6")
#: Interval boundaries of Section 4.2.1 (Hz): 0.5 Hz from 2 to 8 Hz, then 9, 10, 11, 13, 16, 21.
INTERVAL_EDGES_HZ = tuple(float(x) for x in np.arange(2.0, 8.0 + 1e-9, 0.5)) + (9.0, 10.0, 11.0, 13.0, 16.0, FIT_RANGE_MAX_HZ)
#: The study's damping ladder runs up to this Δζ (fraction) first, the rest only where the root
#: lies above (:class:`~adm_calib.calibrate.CalibrationOptions` ``ladder_first_stage``; same brackets).
LADDER_FIRST_STAGE = 0.01
#: Environment of the worker processes: one BLAS/OpenMP thread each (one case per core).
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


# ====================================================================== cases
@dataclass(frozen=True)
class StudyCase:
    """One (bridge, train) pair of the study; ``bridge`` is an :class:`adm_sim.model.bridge.Bridge`.

    The identity is carried as fields: ``train``, ``span_m``, ``freq_index`` (1..5, LB to UB power
    law of n0) and ``mass_function`` (mu1..mu6, Table 1).
    """

    bridge: object
    train: str
    mass_function: str
    freq_index: int
    span_m: float = float("nan")

    def __post_init__(self):
        if self.span_m != self.span_m:  # not given: the bridge's span
            object.__setattr__(self, "span_m", float(self.bridge.span_m))

    @property
    def key(self):
        return (self.bridge.name, self.train)

    @property
    def batch_key(self):
        """Cases that share a batch: one train and one (span, frequency) pair, so one space step; a
        continuous deck's case is a batch of its own (a compiled batch holds one deck)."""
        if self.bridge.is_continuous:
            return (self.train, self.span_m, self.freq_index, self.mass_function)
        return (self.train, self.span_m, self.freq_index)

    def __repr__(self):
        return f"StudyCase({self.bridge.name} x {self.train}, n0={self.bridge.n0_hz:.3f} Hz)"


def paper_train(name):
    """The study train a result's ``train`` stands for: the paper train of a variant, else ``name``."""
    return TRAIN_VARIANTS.get(name, name)


def _variant_name(text):
    key = re.sub(r"[^a-z0-9]", "", str(text).lower())
    return next((v for v in TRAIN_VARIANTS if re.sub(r"[^a-z0-9]", "", v.lower()) == key), None)


def canonical_trains(names, field="trains"):
    """Study train names for ``names`` (duplicates dropped, order kept); ``field`` names the input.

    A shipped variant (:data:`TRAIN_VARIANTS`, e.g. ``Eurostar-table``) keeps its own name.
    """
    out = []
    for t in names:
        name = _variant_name(t)
        try:
            name = name or canonical_train_name(t)
        except InputError:
            raise InputError(f"{field}: {t!r} is not a study train; allowed {', '.join(STUDY_TRAINS)} "
                             f"or the variant {', '.join(TRAIN_VARIANTS)}") from None
        if name not in out:
            out.append(name)
    return out


def select_cases(trains=STUDY_TRAINS, mass_functions=MASS_FUNCTION_NAMES, spans_m=SPAN_RANGE_M,
                 freq_indices=FREQ_INDICES, own=(), *, spans_layout=1):
    """The study cases of the field filtered by the arguments, in a fixed order.

    Parameters
    ----------
    trains : sequence of str
        Study trains (ICE-2, Eurostar, Railjet, ICE-4; case and dashes ignored).
    mass_functions : sequence of str
        Subset of ``mu1``..``mu6`` (Table 1).
    spans_m : (float, float)
        Inclusive span range (m), within [4, 40].
    freq_indices : sequence of int
        Subset of 1..5 (LB, mid, fit, mid, UB power law of n0, Section 3.1.1).
    own : collection of str
        Names in ``trains`` that are trains read from files (:mod:`adm_calib.study.own_train`),
        taken as they are.
    spans_layout : int
        1: the paper's simply supported spans; 2..6: a continuous deck of that many equal spans of
        each case's span (:func:`deck_case_bridge`).

    Returns
    -------
    list of StudyCase
        Field order (span, frequency index, mass function), the trains innermost.
    """
    tr = []
    for t in trains:
        name = t if t in own else canonical_trains([t])[0]
        if name not in tr:
            tr.append(name)
    for m in mass_functions:
        if m not in MASS_FUNCTION_NAMES:
            raise InputError(f"mass_functions: {m!r} is unknown; allowed {', '.join(MASS_FUNCTION_NAMES)}")
    lo, hi = (check_range("spans", s, "m", *SPAN_RANGE_M) for s in spans_m)
    if lo > hi:
        raise InputError(f"spans: {lo:g}:{hi:g} m is empty; give lo:hi with lo <= hi in [4, 40] m")
    for fi in freq_indices:
        if fi not in FREQ_INDICES:
            raise InputError(f"freq_index: {fi!r} is out of range; allowed integer in [1, 5]")
    layout = check_range("spans_layout", spans_layout, "spans", lo=SPANS_LAYOUTS[0], hi=SPANS_LAYOUTS[-1])
    if int(layout) != layout:
        raise InputError(f"spans_layout: {spans_layout!r} is not a whole number of spans; allowed integer in "
                         f"[{SPANS_LAYOUTS[0]}, {SPANS_LAYOUTS[-1]}]")
    mfs, fis = set(mass_functions), set(freq_indices)
    cases = []
    for L, fi, mf, b in _field():
        if mf in mfs and fi in fis and lo <= L <= hi:
            b = b if layout == 1 else deck_case_bridge(b, int(layout), fi, mf)
            cases.extend(StudyCase(bridge=b, train=t, mass_function=mf, freq_index=fi, span_m=L) for t in tr)
    return cases


def deck_case_bridge(bridge, n_spans, freq_index, mass_function):
    """The continuous deck of a study case: ``n_spans`` equal spans of the field bridge's span L.

    Every span has the field bridge's mu (Table 1, Eq. 19, at L) and EJ (Eq. 18 with L and the n0 of
    the Section 3.1.1 power law at L), so the deck's first frequency is that n0 (the first mode of
    equal spans is the simply supported span's, antisymmetric over the supports) and the field
    bridge is the simply supported span of equal first frequency and equal mass per length. Damping:
    Table 2 with L the span (not the deck length; the spans are equal, so L is the longest span, the rule
    of :func:`adm_sim.model.bridge.deck_damping_pct`), Rayleigh anchored at the deck's modes 1 and 3
    (:meth:`adm_sim.model.bridge.Bridge.modal_damping_ratios`); modes: ``3 n_spans``
    (:data:`DECK_MODES_PER_SPAN`). Name ``"2x15-f3-mu2"``.
    """
    L = float(bridge.span_m)
    return Bridge.continuous((L,) * n_spans, bridge.EJ_Nm2, bridge.mass_per_length_kg_m, bridge.damping_ratio,
                             n_modes=DECK_MODES_PER_SPAN * n_spans, damping_model=bridge.damping_model,
                             name=f"{n_spans}x{L:g}-f{freq_index}-{mass_function}", bridge_type=bridge.bridge_type)


@lru_cache(maxsize=1)
def _field():
    """The field as ``(span_m, freq_index, mass_function, bridge)``, in the order of
    :func:`adm_sim.model.bridge.parametric_field` (span, frequency index, mass function)."""
    ids = [(float(L), fi, m) for L in FIELD_SPANS_M for fi in FREQ_INDICES for m in MASS_FUNCTIONS]
    field = parametric_field()
    if len(ids) != len(field):
        raise RuntimeError("the parametric field and its identities disagree")
    return tuple((L, fi, m, b) for (L, fi, m), b in zip(ids, field))


@lru_cache(maxsize=8)
def _train(name):
    return load_train(name)


# ====================================================================== settings and one case
@dataclass(frozen=True)
class StudySettings:
    """Calibration settings shared by every case of one study (all runs into one results file).

    ``speeds`` is the MLM speed grid ``start:stop:step`` in km/h (Section 3.3: 160:350:1),
    ``dim_grid`` and ``steps_per_period`` as for :class:`~adm_calib.calibrate.CalibrationOptions`
    (``None``: the core's default; ``dim_grid`` ``window`` by default: the paper's DIM speeds where
    the associated peak can lie, the same Δζ as ``paper``, the shipped study's grid). The adapted MLM curve is never computed (not needed here).
    ``dense_maxima`` takes the maxima between time samples (dense output,
    :class:`~adm_sim.integrate.step_grid.StepOptions`); ``refine_speed`` locates both peaks to 0.05 km/h
    (:class:`~adm_calib.calibrate.CalibrationOptions` ``speed_refinement_kmh``). Both off: the
    paper's rules. Settings written by a version without these two read as off.
    ``irregularity`` a track profile spec of :func:`adm_sim.inputs.track_profile.parse_irregularity` (e.g.
    ``german-high:seed=3``) applied on the deck of every case (DIM only); empty: smooth track,
    as the paper (and settings written before it existed). ``spans_layout`` the cases' decks
    (:func:`select_cases`): 1, the paper's simply supported spans (and settings written before it
    existed); N, continuous decks of N equal spans.
    """

    speeds: str = DEFAULT_SPEEDS
    dim_grid: str = "window"
    steps_per_period: float | None = None
    dense_maxima: bool = False
    refine_speed: bool = False
    irregularity: str = ""
    spans_layout: int = 1

    def speeds_kmh(self):
        return parse_speeds(self.speeds)

    def calibration_options(self, span_m=None):
        """The calibration options; with an irregularity, ``span_m`` (the cases' span) sets the
        deck the profile is generated on."""
        step = None
        profile = None
        if self.irregularity:
            if span_m is None:
                raise ValueError("calibration_options: an irregularity needs the span of the cases")
            profile = parse_irregularity(self.irregularity, span_m)
        if self.steps_per_period is not None or self.dense_maxima or profile is not None:
            spp = StepOptions.steps_per_period if self.steps_per_period is None else self.steps_per_period
            step = StepOptions(steps_per_period=spp,
                               dense_maxima=bool(self.dense_maxima), irregularity=profile)
        refine = REFINED_SPEED_STEP_KMH if self.refine_speed else None
        return CalibrationOptions(dim_grid=self.dim_grid, step=step, speed_refinement_kmh=refine, xtol=XTOL_STUDY,
                                  ladder_first_stage=LADDER_FIRST_STAGE)

    def to_dict(self):
        return asdict(self)


def case_identity(bridge, train, mass_function, freq_index):
    """The identity fields of a result line (SI except ``mu_t_m`` in t/m and ``zeta_pct`` in %); a
    continuous deck's also name its spans, length and mode count (``span_m`` is then its span)."""
    rec = {
        "bridge": bridge.name, "train": train, "span_m": float(bridge.span_m), "n0_hz": float(bridge.n0_hz),
        "mu_t_m": float(bridge.mass_per_length_kg_m) / 1000.0, "mass_function": mass_function,
        "freq_index": int(freq_index), "bridge_type": bridge.bridge_type,
        "zeta_pct": 100.0 * float(bridge.damping_ratio),
    }
    if bridge.is_continuous:  # span_m: the span the field's laws were applied to; the deck beside it
        rec.update({"span_m": float(max(bridge.spans_m)), "spans_m": [float(x) for x in bridge.spans_m],
                    "deck_length_m": float(bridge.span_m), "n_modes": int(bridge.n_modes)})
    return rec
