"""Whole speed sweeps in one call: every speed is a lane of one vectorised lockstep run.

``run_sweep`` advances one :class:`adm_sim.integrate.lockstep_runs.InProcessRun` a whole step at a time; the ROS
bridge and train nodes each drive their half of the same object stage by stage (one exchange per
RK4 stage), so a co-simulation reproduces these numbers bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from adm_sim.errors import InputError, RunError
from adm_sim.fields import check_delta_zeta_fraction
from adm_sim.integrate.contact import CONTACT_LOST, CONTACT_OK
from adm_sim.limits import check_memory
from adm_sim.integrate.peaks import largest_interior_peak
from adm_sim.integrate.lockstep_runs import InProcessRun
from adm_sim.integrate.mlm_loads import mlm_modal_load_table
from adm_sim.integrate.rk4_sides import BridgeSide, TrainSide
from adm_sim.integrate.run_contract import FAILED, RUNNING, check_model
from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s

MAX_HISTORY_VALUES = 300_000_000


@dataclass(frozen=True, repr=False)
class SweepResult:
    """Result of a speed sweep.

    Attributes
    ----------
    speeds_kmh : ndarray (n_lanes,)
    max_acc_m_s2 : ndarray (n_lanes,)
        Max |midspan acceleration| over the crossing and the free vibration.
    max_disp_m : ndarray (n_lanes,)
        Max |midspan deflection|.
    time_s, midspan_disp_m, midspan_acc_m_s2 : ndarray (n_lanes, n_steps) or None
        Histories (``histories=True``).
    contact_force_n : ndarray (n_lanes, n_steps, n_axles) or None
        DIM wheel-rail contact forces (Eq. 7; zero off the bridge), with histories.
    contact : adm_sim.integrate.contact.ContactCheck or None
        DIM: the smallest contact force and the first tension per lane (None for the MLM).
    """

    model: str
    bridge: object
    train_name: str
    speeds_kmh: np.ndarray
    max_acc_m_s2: np.ndarray
    max_disp_m: np.ndarray
    delta_zeta: np.ndarray
    ds_m: float
    n_steps: int
    time_s: np.ndarray | None = field(default=None)
    midspan_disp_m: np.ndarray | None = field(default=None)
    midspan_acc_m_s2: np.ndarray | None = field(default=None)
    contact_force_n: np.ndarray | None = field(default=None)
    method: str = "rk4"
    contact: object = field(default=None)

    @property
    def status(self):
        """``"contact_lost"`` when a DIM wheel would lift off at some speed, else ``"ok"``."""
        return CONTACT_OK if self.contact is None else self.contact.status

    def peak(self):
        """``{"speed_kmh", "acc_m_s2", "index"}`` of the peak of the curve, or None.

        The peak rule of :mod:`adm_sim.integrate.peaks` (highest interior local maximum, 0.1 % prominence),
        the one ``adm-calib calibrate`` uses.
        """
        i = largest_interior_peak(self.max_acc_m_s2)
        if i is None:
            return None
        return {"speed_kmh": float(self.speeds_kmh[i]), "acc_m_s2": float(self.max_acc_m_s2[i]), "index": i}

    def to_dict(self):
        pk = self.peak()
        return {
            "model": self.model,
            "method": self.method,
            "bridge": self.bridge.describe(),
            "train": self.train_name,
            "delta_zeta_pct": (100.0 * self.delta_zeta).tolist() if np.ndim(self.delta_zeta) else 100.0 * float(self.delta_zeta),
            "ds_m": self.ds_m,
            "n_steps": self.n_steps,
            "speeds_kmh": self.speeds_kmh.tolist(),
            "max_acc_m_s2": self.max_acc_m_s2.tolist(),
            "max_disp_m": self.max_disp_m.tolist(),
            "peak": None if pk is None else {"speed_kmh": pk["speed_kmh"], "acc_m_s2": pk["acc_m_s2"]},
            "spans_m": list(self.bridge.spans_m) if self.bridge.is_continuous else [self.bridge.span_m],
            "frequencies_hz": self.bridge.frequencies_hz.tolist(),
            "modal_masses_kg": self.bridge.modal_mass_kg.tolist(),
            "status": self.status,
            **({} if self.contact is None else {"contact": self.contact.to_dict()}),
        }

    def __repr__(self):
        pk = self.peak()
        where = "no interior peak" if pk is None else f"peak {pk['acc_m_s2']:.4f} m/s2 at {pk['speed_kmh']:g} km/h"
        how = "exact envelope" if self.method == "exact" else f"{self.n_steps} steps of {self.ds_m * 1000:.2f} mm"
        return (f"SweepResult({self.model.upper()}, {self.bridge.name or 'bridge'} x {self.train_name}, "
                f"{len(self.speeds_kmh)} speeds {self.speeds_kmh.min():g}..{self.speeds_kmh.max():g} km/h, "
                f"{where}, {how}{', CONTACT LOST' if self.status == CONTACT_LOST else ''})")


def sweep_exact(bridge, train, speeds_kmh, delta_zeta=0.0, where="midspan", *, delta_zeta_name="delta_zeta",
                remedy=""):
    """The MLM sweep by the exact envelope (:func:`adm_sim.integrate.envelope.moving_load_envelope`): the true
    maximum per speed, not the largest RK4 step sample (which sits up to 0.66 % below it on B1 x
    ICE-2 at 16 steps per period). Returns ``(SweepResult, Envelope)``; the result's
    ``max_acc_m_s2`` / ``max_disp_m`` are taken at ``where`` (``"midspan"``, ``"deck"`` or x in m).
    ``delta_zeta_name``: as :func:`run_sweep`; ``remedy``: text added to the refusal of ζ + Δζ = 0.
    """
    from adm_sim.integrate.envelope import moving_load_envelope  # noqa: PLC0415  numba kernels: only the exact sweep needs them

    env = moving_load_envelope(bridge, train.axle_offsets_m, train.axle_loads_n, speeds_kmh,
                               delta_zeta=delta_zeta, where=where, delta_zeta_name=delta_zeta_name,
                               positive_for="the exact MLM envelope", remedy=remedy)
    res = SweepResult(model="mlm", bridge=bridge, train_name=train.name, speeds_kmh=env.speeds_kmh.copy(),
                      max_acc_m_s2=env.max_acc_m_s2, max_disp_m=env.max_disp_m,
                      delta_zeta=np.asarray(delta_zeta, dtype=float), ds_m=0.0, n_steps=0, method="exact")
    return res, env


def lane_damping(bridge, delta_zeta, shape, name="delta_zeta", **kw):
    """The additional damping Δζ of every lane (fractions), ``delta_zeta`` broadcast to ``shape``:
    the one check of a sweep's Δζ, each distinct value once, the refusal naming ``name`` in its unit
    (:func:`adm_sim.fields.check_delta_zeta_fraction`: ``delta_zeta`` a fraction, ``--delta-zeta-pct``
    in %); keywords as :func:`adm_sim.fields.check_delta_zeta`. ``name=None``: the caller has checked
    ``delta_zeta`` with this function already (the command line, before it prints), not checked again."""
    dz = np.broadcast_to(np.asarray(delta_zeta, dtype=float), shape)
    if name is None:  # the caller checked it with this function (a command line, before its first output)
        return dz
    for x in np.unique(dz):
        check_delta_zeta_fraction(name, float(x), bridge.damping_ratio, **kw)
    return dz


def check_spans_for_train(bridge, train):
    """Refuse a continuous deck with a span shorter than the train's longest axle group (its largest
    bogie wheelbase ``b_m``; trains given as bare axle loads carry no groups and pass)."""
    if bridge.is_continuous:
        check_span_lengths(bridge.spans_m, train)


def check_span_lengths(spans_m, train):
    """:func:`check_spans_for_train` of the spans ``spans_m`` (m) of a deck (where only its spans are
    at hand: the bridge's description record in the train node)."""
    groups = [vt.b_m for vt in train.vehicle_types.values()]
    if not groups:
        return
    b = max(groups)
    for i, L in enumerate(spans_m):
        if L < b:
            raise InputError(f"spans[{i}]: {L:g} m is shorter than the longest axle group of {train.name} "
                             f"(bogie wheelbase {b:g} m); allowed spans >= {b:g} m")


def _response_m(bridge, model, where):
    """The response point of an RK4 sweep (None: midspan) from ``where`` (``"midspan"`` or x in m);
    refuses what the RK4 runs do not take on this bridge."""
    if isinstance(where, str):
        w = where.strip().lower()
        if w == "midspan":
            return None
        raise InputError(f"where: {where!r} is not allowed for an RK4 run; allowed midspan or x=<m> with "
                         f"0 < x < {bridge.span_m:g} m (deck: the exact MLM envelope, one span only)", field="where")
    return float(where)


#: Backends of a sweep: the compiled kernels (default) and the numpy stepper they are tested against.
BACKENDS = ("compiled", "numpy")


def run_sweep_compiled(bridge, train, model, speeds_kmh, delta_zeta=0.0, options=None, progress=None,
                       where="midspan", *, delta_zeta_name="delta_zeta"):
    """:func:`run_sweep` on the compiled kernels: every speed a lane of one
    :class:`adm_sim.integrate.compiled_batch.BatchRun`, on the grid ``run_sweep`` makes (its ``ds`` and
    number of steps), so the maxima equal the numpy stepper's to ~1e-13 relative (the summation
    order of a few small dot products differs; ``tests/integrate/test_sweep_backends.py`` holds them to
    1e-12). No histories. ``progress(done_steps, n_steps)`` is called after every block of steps
    (about 100 per run). ``where``: ``"midspan"`` or a position x (m from the left abutment).
    ``delta_zeta_name``: as :func:`run_sweep`.
    """
    from adm_sim.integrate.compiled_batch import BatchRunner  # noqa: PLC0415  deferred: heavy import (numba, ~0.4 s)

    check_model(model, train)
    check_spans_for_train(bridge, train)
    response_m = _response_m(bridge, model, where)
    options = options or StepOptions()
    v_kmh = np.atleast_1d(np.asarray(speeds_kmh, dtype=float)).copy()
    v = speeds_to_m_s(v_kmh)
    dz = lane_damping(bridge, delta_zeta, v.shape, delta_zeta_name)
    grid = make_grid(bridge, train.length_m, v, options)
    runner = BatchRunner([bridge], train, grid.ds_m, options.free_vibration_periods, options.dense_maxima,
                         response_m=response_m, irregularity=options.irregularity if model == "dim" else None)
    run = runner.start(model, np.zeros(v.size, dtype=np.int64), v_kmh, dz)
    if run.n_steps != grid.n_steps:  # pragma: no cover - the same make_grid on both sides
        raise RunError(f"compiled sweep: {run.n_steps} steps where the grid has {grid.n_steps}")
    block = None if progress is None else max(1, -(-run.n_steps // 100))
    while run.status == RUNNING:
        run.advance(block)
        if progress is not None:
            progress(run.k, run.n_steps)
    if run.status == FAILED:
        raise RunError(run.message)
    return SweepResult(model=model, bridge=bridge, train_name=train.name, speeds_kmh=v_kmh,
                       max_acc_m_s2=run.max_acc_m_s2, max_disp_m=run.max_disp_m,
                       delta_zeta=np.asarray(delta_zeta, dtype=float), ds_m=grid.ds_m, n_steps=grid.n_steps,
                       contact=run.contact)


def sweep_bytes(model, n_steps, n_lanes, n_modes, n_axles, histories):
    """Memory of the tables and histories of :func:`run_sweep` (bytes): the MLM's modal-load table
    ``(2 n + 1) x n_modes`` (built axle by axle on one span, :func:`adm_sim.integrate.mlm_loads.span_load_table`),
    and with ``histories`` the times, deflections and accelerations ``n_lanes x n_steps`` each and the
    DIM's contact forces ``n_lanes x n_steps x n_axles``, in doubles."""
    kept = (2.0 * n_steps + 1.0) * n_modes * (0 if model == "dim" else 1)
    kept += float(n_lanes) * n_steps * (3 + (n_axles if model == "dim" else 0)) if histories else 0.0
    return 8.0 * kept


def run_sweep(bridge, train, model, speeds_kmh, delta_zeta=0.0, options=None, histories=False,
              progress=None, where="midspan", *, delta_zeta_name="delta_zeta"):
    """Max midspan acceleration of a bridge under a train for every speed, in one vectorised run.

    Parameters
    ----------
    bridge : adm_sim.model.bridge.Bridge
    train : adm_sim.model.trains.Train
    model : {"mlm", "dim"}
        Moving Load Model (Eqs. 5, 6, 12) or Detailed Interaction Model (Eqs. 7-17).
    speeds_kmh : array_like (n_lanes,)
    delta_zeta : float or array_like (n_lanes,)
        Additional damping (fraction) on top of ``bridge.damping_ratio``.
    options : StepOptions, optional
    histories : bool
        Keep time histories (memory: ``n_lanes * n_steps`` per quantity, the times included). They are
        the result, so they are allocated whole, once, in the layout they are returned in (no
        transposed copy at the end), not in chunks; :data:`MAX_HISTORY_VALUES` caps them.
    progress : callable(done_steps, n_steps) or None
        Called about 100 times during the run.
    where : "midspan" or float
        Where the maxima and histories are taken: midspan (a continuous deck: the middle of its
        longest span, ``bridge.midspan_m``) or a position x (m from the left abutment).
    delta_zeta_name : str
        How the caller named ``delta_zeta`` (:func:`lane_damping`): ``"delta_zeta"`` (a fraction) or
        the command line's ``"--delta-zeta-pct"`` (the refusal in %); None: the caller checked it.

    Returns
    -------
    SweepResult
    """
    check_model(model, train)
    check_spans_for_train(bridge, train)
    response_m = _response_m(bridge, model, where)
    v = speeds_to_m_s(speeds_kmh)
    dz = lane_damping(bridge, delta_zeta, v.shape, delta_zeta_name)
    options = options or StepOptions()
    grid = make_grid(bridge, train.length_m, v, options)
    n, nl = grid.n_steps, grid.n_lanes
    dim = model == "dim"
    if histories and nl * n * (1 + (train.n_axles if dim else 0)) > MAX_HISTORY_VALUES:
        raise InputError(f"histories: {nl} speeds x {n} steps is too much to keep; "
                         f"ask histories for at most a few speeds")
    check_memory(sweep_bytes(model, n, nl, bridge.n_modes, train.n_axles, histories),
                 f"the {model.upper()} run's tables{' and histories' if histories else ''}",
                 f"large because {n} steps of ds = {grid.ds_m * 1e3:.3g} mm x {nl} speeds; fewer steps per period "
                 f"or fewer speeds make it smaller")
    b = BridgeSide(bridge, grid, train.axle_offsets_m, train.wheel_mass_kg if dim else None, dz, response_m=response_m)
    if dim:
        run = InProcessRun(model, grid, b, train_side=TrainSide(train, grid, bridge.span_m,
                                                                     irregularity=options.irregularity),
                           dense_maxima=options.dense_maxima)
    else:
        run = InProcessRun(model, grid, b, dense_maxima=options.dense_maxima,
                           modal_loads=mlm_modal_load_table(bridge, grid, train.axle_offsets_m, train.axle_loads_n))
    acc = np.empty((nl, n)) if histories else None  # (lanes, steps): the layout of the result
    disp = np.empty((nl, n)) if histories else None
    forces = np.zeros((nl, n, train.n_axles), dtype=np.float64) if (histories and dim) else None
    tick = max(1, n // 100)
    for k in range(n):
        if disp is not None:
            disp[:, k] = run.disp_m
        if run.step() is not None:
            raise RunError(run.message)
        if acc is not None:
            acc[:, k] = run.acc_m_s2
        if forces is not None:
            idx, f = run.contact_forces_n()
            if len(idx):
                forces[:, k][:, idx] = f
        if progress is not None and (k % tick == 0 or k == n - 1):
            progress(k + 1, n)
    kw = {}
    if histories:
        kw = dict(time_s=np.outer(1.0 / v, np.arange(n) * grid.ds_m), midspan_disp_m=disp, midspan_acc_m_s2=acc,
                  contact_force_n=forces)
    return SweepResult(model=model, bridge=bridge, train_name=train.name,
                       speeds_kmh=np.atleast_1d(np.asarray(speeds_kmh, dtype=float)).copy(), max_acc_m_s2=run.max_acc_m_s2,
                       max_disp_m=run.max_disp_m, delta_zeta=np.asarray(delta_zeta, dtype=float),
                       ds_m=grid.ds_m, n_steps=n, contact=run.contact, **kw)
