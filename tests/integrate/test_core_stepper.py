"""The numpy stepper (lockstep_runs.InProcessRun, BridgeHalf, TrainHalf on the run_contract.SteppedRun template):
status, step/stage bookkeeping, maxima, finite check.

Short case: bridge B1 x ICE-2 at 160, 250 and 350 km/h; both models on a coarse grid (4 steps per
period of mode 3, one period of free vibration) to keep it quick: the bookkeeping and the bit-for-bit
promise hold at any step, and the MLM's halves advanced one step per call are a Python call per step
(2537 steps here, 10460 on the default grid). Maxima are compared with ``run_sweep`` bit for bit
(tolerance 0), as the co-simulation promises.
"""

import numpy as np
import pytest

from adm_sim.model.bridge import named_bridge
from adm_sim.errors import InputError, RunError
from adm_sim.integrate.lockstep_runs import BridgeHalf, InProcessRun, TrainHalf
from adm_sim.integrate.mlm_loads import half_step_positions, mlm_modal_load_table, modal_loads_at
from adm_sim.integrate.rk4_sides import BridgeSide, TrainSide
from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s
from adm_sim.integrate.sweep import run_sweep
from adm_sim.inputs.train_files import load_train

SPEEDS_KMH = [160.0, 250.0, 350.0]
DIM_OPTIONS = StepOptions(steps_per_period=4.0, free_vibration_periods=1.0)
MLM_OPTIONS = StepOptions(steps_per_period=4.0, free_vibration_periods=1.0)  # as the DIM's: MLM maxima 0.38, 1.0, 2.1 m/s2
BRIDGE, TRAIN = named_bridge("B1"), load_train("ICE-2")


def grid_of(options):
    return make_grid(BRIDGE, TRAIN.length_m, speeds_to_m_s(SPEEDS_KMH), options)


def bridge_side(grid, model):
    return BridgeSide(BRIDGE, grid, TRAIN.axle_offsets_m, TRAIN.wheel_mass_kg if model == "dim" else None)


def in_process(model, options):
    """A run holding both halves, as run_sweep builds it."""
    grid = grid_of(options)
    if model == "dim":
        return InProcessRun("dim", grid, bridge_side(grid, "dim"), train_side=TrainSide(TRAIN, grid, BRIDGE.span_m))
    table = mlm_modal_load_table(BRIDGE, grid, TRAIN.axle_offsets_m, TRAIN.axle_loads_n)
    return InProcessRun("mlm", grid, bridge_side(grid, "mlm"), modal_loads=table)


@pytest.fixture(scope="module")
def reference():
    """run_sweep with histories, per model."""
    return {"mlm": run_sweep(BRIDGE, TRAIN, "mlm", SPEEDS_KMH, options=MLM_OPTIONS, histories=True),
            "dim": run_sweep(BRIDGE, TRAIN, "dim", SPEEDS_KMH, options=DIM_OPTIONS, histories=True)}


def assert_bitwise(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype
    assert a.tobytes() == b.tobytes(), np.max(np.abs(a - b))


def test_mlm_status_bookkeeping_and_maxima(reference):
    run = in_process("mlm", MLM_OPTIONS)
    n = run.n_steps
    assert n > 100
    assert (run.k, run.stage, run.status, run.message) == (0, 0, "running", "")
    np.testing.assert_array_equal(run.max_acc_m_s2, 0.0)
    np.testing.assert_array_equal(run.max_disp_m, 0.0)  # the bridge starts at rest
    for k in range(n):
        assert (run.k, run.stage, run.status) == (k, 0, "running")
        assert run.step() is None
    assert (run.k, run.stage, run.status, run.message) == (n, 0, "finished", "")
    with pytest.raises(RuntimeError, match=f"the run is finished at step {n} of {n}"):
        run.step()
    ref = reference["mlm"]
    assert ref.n_steps == n
    assert_bitwise(run.max_acc_m_s2, ref.max_acc_m_s2)
    assert_bitwise(run.max_disp_m, ref.max_disp_m)
    # and the maxima are those of the histories (acceleration at stage 0, deflection at step start)
    assert_bitwise(run.max_acc_m_s2, np.abs(ref.midspan_acc_m_s2).max(axis=1))
    assert_bitwise(run.max_disp_m, np.abs(ref.midspan_disp_m).max(axis=1))
    assert np.all(run.max_acc_m_s2 > 0.3)  # m/s^2: a real response (B1 x ICE-2 peaks ~0.4..2.2)


def test_dim_stage_bookkeeping_and_maxima(reference):
    run = in_process("dim", DIM_OPTIONS)
    n = run.n_steps
    # advance(n) is n steps; step() is one
    assert run.advance(2) is None
    assert (run.k, run.stage, run.status) == (2, 0, "running")
    with pytest.raises(ValueError, match="InProcessRun.advance: max_steps = 0 must be >= 1"):
        run.advance(0)
    while run.status == "running":
        k = run.k
        assert run.step() is None
        assert (run.k, run.stage) == (k + 1, 0)
    assert (run.k, run.status, run.message) == (n, "finished", "")
    ref = reference["dim"]
    assert_bitwise(run.max_acc_m_s2, ref.max_acc_m_s2)
    assert_bitwise(run.max_disp_m, ref.max_disp_m)
    assert_bitwise(run.max_acc_m_s2, np.abs(ref.midspan_acc_m_s2).max(axis=1))
    assert_bitwise(run.max_disp_m, np.abs(ref.midspan_disp_m).max(axis=1))
    # contact forces of the last step: no axle on the bridge in the free vibration
    idx, f = run.contact_forces_n()
    assert idx.size == 0 and f.shape == (3, 0)


def test_dim_halves_reproduce_in_process(reference):
    """Bridge half and train half driven as the two nodes drive them (copies = the exchange)."""
    grid = grid_of(DIM_OPTIONS)
    bh = BridgeHalf("dim", grid, bridge_side(grid, "dim"))
    th = TrainHalf("dim", grid, TrainSide(TRAIN, grid, BRIDGE.span_m))
    with pytest.raises(TypeError, match=r"BridgeHalf.step: the DIM takes the interaction forces of one RK4 stage "
                                        r"\(1 argument\), got 3"):
        bh.step(None, None, None)
    with pytest.raises(TypeError, match=r"TrainHalf.step: the DIM takes the rail state .* \(3 arguments\), got 0"):
        th.step()
    with pytest.raises(RuntimeError, match="TrainHalf.advance: needs the MLM"):
        th.advance(1)
    assert not hasattr(bh, "advance") and not hasattr(bh, "take_forces") and not hasattr(th, "take_rail_state")
    assert (bh.k, bh.stage, th.k, th.stage) == (0, 0, 0, 0)  # the refused calls moved nothing
    while bh.status == "running":
        assert (th.k, th.stage, th.status) == (bh.k, bh.stage, "running")
        k, stage = bh.k, bh.stage
        idx, w, wd = bh.rail_state()
        assert (bh.k, bh.stage) == (k, stage)  # the rail state is a query: it does not advance
        assert th.step(idx.copy(), w.copy(), wd.copy()) is None
        G = th.interaction_n
        assert (th.k, th.stage) == ((k, stage + 1) if stage < 3 else (k + 1, 0))  # train half: stage done
        assert bh.step(G.copy()) is None
        assert (bh.k, bh.stage) == (th.k, th.stage)
    assert bh.status == th.status == "finished" and bh.k == th.k == grid.n_steps
    ref = reference["dim"]
    assert_bitwise(bh.max_acc_m_s2, ref.max_acc_m_s2)
    assert_bitwise(bh.max_disp_m, ref.max_disp_m)


@pytest.mark.slow
@pytest.mark.parametrize("block", [1, 37, 10**7])
def test_mlm_halves_reproduce_in_process(reference, block):
    """Train half books blocks of axle positions, bridge half steps them (as the two nodes)."""
    grid = grid_of(MLM_OPTIONS)
    bh = BridgeHalf("mlm", grid, bridge_side(grid, "mlm"))
    th = TrainHalf("mlm", grid)
    while th.status == "running":
        assert (th.k, th.stage) == (bh.k, 0)
        k0 = th.k
        assert th.advance(block) is None
        nb = th.k - k0
        assert k0 == bh.k and nb == min(block, grid.n_steps - k0)
        P = modal_loads_at(BRIDGE, half_step_positions(grid.ds_m, TRAIN.axle_offsets_m, k0, nb), TRAIN.axle_loads_n)
        for j in range(nb):
            assert bh.step(P[2 * j], P[2 * j + 1], P[2 * j + 2]) is None
    assert bh.status == "finished" and bh.k == th.k == grid.n_steps
    with pytest.raises(RuntimeError, match="TrainHalf.advance: the run is finished"):
        th.advance(block)
    ref = reference["mlm"]
    assert_bitwise(bh.max_acc_m_s2, ref.max_acc_m_s2)
    assert_bitwise(bh.max_disp_m, ref.max_disp_m)


def test_unstable_step_fails_with_a_message():
    """ds = 5 m is far beyond the RK4 stability limit of mode 3 at 160 km/h: the run fails."""
    opts = StepOptions(ds_m=5.0)
    with np.errstate(all="ignore"):
        with pytest.raises(RunError, match=r"^solution is not finite at step \d+ of \d+ \(stage 0\): midspan "):
            run_sweep(BRIDGE, TRAIN, "dim", SPEEDS_KMH, options=opts)
        run = in_process("dim", opts)
        while run.status == "running":
            msg = run.step()
    assert run.status == "failed" and msg == run.message
    assert "\n" not in run.message and "(first at 160 km/h)" in run.message
    assert "ds = 5 m is too large" in run.message
    assert 0 < run.k < run.n_steps and run.message.startswith(f"solution is not finite at step {run.k} of ")
    assert np.all(np.isfinite(run.max_acc_m_s2)) and np.all(np.isfinite(run.max_disp_m))
    with pytest.raises(RuntimeError, match="the run is failed at step"):
        run.step()


def test_injected_nan_fails_and_keeps_the_maxima():
    run = in_process("mlm", MLM_OPTIONS)
    for _ in range(400):
        run.step()
    before_acc, before_disp = run.max_acc_m_s2.copy(), run.max_disp_m.copy()
    assert np.all(before_disp > 0.0)
    run.bridge_side.rk.x[1, 0] = np.nan  # mode 1 of the 250 km/h lane
    msg = run.step()
    assert run.status == "failed" and run.k == 400
    assert msg == (f"solution is not finite at step 400 of {run.n_steps} (stage 0): midspan acceleration in 1 of "
                   f"3 lanes (first at 250 km/h); the step ds = {run.grid.ds_m:.4g} m is too large for this "
                   f"bridge/train (raise steps_per_period or lower ds_m)")
    assert_bitwise(run.max_acc_m_s2, before_acc)
    assert_bitwise(run.max_disp_m, before_disp)


def test_nan_force_on_the_bridge_half_fails_at_the_next_step():
    """A non-finite interaction force at stage 1 shows in the deflection at the start of k + 1."""
    grid = grid_of(DIM_OPTIONS)
    bh = BridgeHalf("dim", grid, bridge_side(grid, "dim"))
    th = TrainHalf("dim", grid, TrainSide(TRAIN, grid, BRIDGE.span_m))
    while bh.k < 300:  # the first axles are on the bridge by then
        idx, w, wd = bh.rail_state()
        th.step(idx, w, wd)
        bh.step(th.interaction_n)
    for stage in range(4):
        idx, w, wd = bh.rail_state()
        th.step(idx, w, wd)
        G = th.interaction_n
        assert idx.size > 0
        if stage == 1:
            G = G.copy()
            G[2, 0] = np.nan  # 350 km/h lane
        msg = bh.step(G)
    assert bh.status == "failed" and (bh.k, bh.stage) == (301, 0) and msg == bh.message
    assert "at step 301 of" in bh.message and "midspan deflection in 1 of 3 lanes (first at 350 km/h)" in bh.message
    assert np.all(np.isfinite(bh.max_disp_m)) and np.all(np.isfinite(bh.max_acc_m_s2))
    with pytest.raises(RuntimeError, match="BridgeHalf.step: the run is failed at step 301"):
        bh.step(G)
    with pytest.raises(RuntimeError, match="BridgeHalf.rail_state: the run is failed at step 301"):
        bh.rail_state()


def test_contract_refuses_misuse():
    grid = grid_of(MLM_OPTIONS)
    side = bridge_side(grid, "mlm")
    with pytest.raises(InputError, match="model: 'xyz' is not allowed"):
        TrainHalf("xyz", grid)
    with pytest.raises(InputError, match="model: 'xyz' is not allowed"):
        InProcessRun("xyz", grid, side)
    with pytest.raises(ValueError, match="TrainHalf: the MLM has no train side"):
        TrainHalf("mlm", grid, TrainSide(TRAIN, grid, BRIDGE.span_m))
    with pytest.raises(ValueError, match="InProcessRun: the MLM has no train side .* and needs the modal-load"):
        InProcessRun("mlm", grid, side)
    with pytest.raises(ValueError, match="InProcessRun: the DIM needs a train side"):
        InProcessRun("dim", grid, side)
    run = BridgeHalf("mlm", grid, side)
    with pytest.raises(RuntimeError, match="BridgeHalf.rail_state: needs the DIM"):
        run.rail_state()
    with pytest.raises(TypeError, match=r"BridgeHalf.step: the MLM takes the modal loads p0, ph, p1 of one step "
                                        r"\(3 arguments\), got 1"):
        run.step(np.zeros((3, 0)))
    assert (run.k, run.status) == (0, "running")
    P = mlm_modal_load_table(BRIDGE, grid, TRAIN.axle_offsets_m, TRAIN.axle_loads_n)
    run.step(P[0], P[1], P[2])
    with pytest.raises(ValueError, match="BridgeHalf: BridgeSide is at step 1, not at step 0"):
        BridgeHalf("mlm", grid, side)


def test_an_implementation_reports_and_only_step_sets_the_status():
    """``_step_impl`` returns ``(success, message)`` and leaves status and message to ``step``."""
    run = in_process("mlm", MLM_OPTIONS)
    for _ in range(10):
        run.step()
    run.bridge_side.rk.x[0, 0] = np.inf  # the 160 km/h lane
    with np.errstate(invalid="ignore", over="ignore"):
        success, message = run._step_impl()
    assert not success and message.startswith(f"solution is not finite at step 10 of {run.n_steps} (stage 0): "
                                              f"midspan acceleration in 1 of 3 lanes (first at 160 km/h)")
    assert (run.status, run.message) == ("running", "")
    assert run._settle(success, message) == message and (run.status, run.message) == ("failed", message)
