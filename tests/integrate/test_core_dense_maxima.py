"""Maxima between time samples from the integrator's dense output (quintic Hermite, Eq. 12/15 data).

References independent of the solvers:

* a damped free vibration in closed form: the extrema of x'' are where x''' = 0 (exact times);
* one force crossing a single-mode beam (Fryba's closed form, tests/analytic.py) evaluated on a
  fine time grid and refined by a local quadratic: the exact largest midspan acceleration;
* for the DIM, no closed form: the same run with an 8 times finer step.

The numpy stepper and the compiled kernels compute the same numbers (one-to-one arithmetic).
"""

import math

import numpy as np
import pytest

from adm_sim.integrate import kernels
from adm_sim.integrate.compiled_batch import BatchRunner
from adm_sim.model.bridge import named_bridge
from adm_sim.integrate.dense_output import hermite_max_abs_acc
from adm_sim.integrate.step_grid import StepOptions, make_grid, speeds_to_m_s
from adm_sim.integrate.sweep import run_sweep
from adm_sim.model.trains import moving_loads
from adm_sim.inputs.train_files import load_train

from analytic import moving_force_modal


def free_vibration(t, omega, zeta):
    """x = Re exp(lambda t), lambda = -zeta omega + i omega_d: x, x', x'' and the exact max |x''|."""
    lam = complex(-zeta * omega, omega * math.sqrt(1 - zeta**2))
    e = np.exp(lam * t)
    return (e.real, (lam * e).real, (lam**2 * e).real), lam


def exact_max_abs_acc(t0, t1, omega, zeta):
    (_, _, a_ends), lam = free_vibration(np.array([t0, t1]), omega, zeta)
    wd, ph3 = lam.imag, math.atan2(lam.imag, lam.real) * 3
    n = np.arange(math.floor((wd * t0 + ph3 - math.pi / 2) / math.pi) - 1,
                  math.ceil((wd * t1 + ph3 - math.pi / 2) / math.pi) + 2)
    tn = (math.pi / 2 + n * math.pi - ph3) / wd  # x''' = Re(lam^3 e^{lam t}) = 0
    tn = tn[(tn > t0) & (tn < t1)]
    (_, _, a_n), _ = free_vibration(tn, omega, zeta)
    return max(np.abs(a_ends).max(), np.abs(a_n).max())


def sampled_and_dense(t, omega, zeta, helper):
    (x, v, a), _ = free_vibration(t, omega, zeta)
    h = np.diff(t)
    inner = helper(x[:-1], v[:-1], a[:-1], x[1:], v[1:], a[1:], h)
    return np.abs(a).max(), max(np.abs(a).max(), inner.max())


def _scalar_helper(fn):
    def f(*args):
        return np.array([fn(*map(float, z)) for z in zip(*args)])
    return f


@pytest.mark.parametrize("helper", [hermite_max_abs_acc, _scalar_helper(kernels.hermite_max_abs_acc),
                                    _scalar_helper(kernels.hermite_max_abs_acc.py_func)],
                         ids=["numpy", "numba", "python"])
def test_free_vibration_maximum_to_fourth_order(helper):
    omega, zeta = 2 * math.pi * 3.0, 0.02
    T = 2 * math.pi / omega
    errs = []
    for n in (8, 16, 32):  # samples per period, offset so that no sample hits an extremum
        h = T / n
        t = T / 4 + 0.37 * h + h * np.arange(3 * n + 1)  # starts near a zero of x''
        exact = exact_max_abs_acc(t[0], t[-1], omega, zeta)
        sampled, dense = sampled_and_dense(t, omega, zeta, helper)
        assert sampled < exact and abs(dense / exact - 1) < 0.2 * (1 - sampled / exact)
        errs.append(abs(dense / exact - 1))
    assert errs[1] <= 1e-4 and errs[2] <= 1e-5          # 16 steps per period: 1e-4 at most
    assert errs[0] / errs[1] > 10 and errs[1] / errs[2] > 10   # fourth order: 16 per halving


def test_helper_numpy_equals_kernel():
    rng = np.random.default_rng(1)
    args = rng.standard_normal((6, 400))
    h = rng.uniform(1e-4, 1e-2, 400)
    ref = hermite_max_abs_acc(*args, h)
    got = np.array([kernels.hermite_max_abs_acc(*map(float, z)) for z in zip(*args, h)])
    np.testing.assert_allclose(got, ref, rtol=1e-13, atol=0.0)
    assert np.count_nonzero(ref) > 100  # most random steps have an interior extremum


# ---------------------------------------------------------------------- MLM, one force, one mode
ONE_FORCE = moving_loads([0.0], [100e3], "one force")


def exact_mlm_max(bridge, speed_m_s, t_end):
    t = np.linspace(0.0, t_end, 400_001)
    q, qd, f = moving_force_modal(bridge, 100e3, speed_m_s, t)
    om = bridge.omega_rad_s[:, None]
    zeta = bridge.modal_damping_ratios(0.0)[:, None]
    phi = np.sin(bridge.mode_numbers * math.pi / 2)[:, None]
    a = np.abs((phi * (f - 2 * zeta * om * qd - om**2 * q)).sum(0))
    i = int(np.argmax(a))
    y0, y1, y2 = a[i - 1], a[i], a[i + 1]   # quadratic through the three samples around the top
    return y1 + 0.125 * (y0 - y2) ** 2 / (2 * y1 - y0 - y2)


def test_mlm_single_force_single_mode_against_closed_form():
    b = named_bridge("B1", n_modes=1)
    speeds = np.array([150.0, 180.0, 215.0, 263.0, 300.0])
    opt = StepOptions(steps_per_period=16.0)
    r = run_sweep(b, ONE_FORCE, "mlm", speeds, options=opt, histories=True)
    sampled = r.max_acc_m_s2
    dense_opt = StepOptions(steps_per_period=16.0, dense_maxima=True)
    dense = run_sweep(b, ONE_FORCE, "mlm", speeds, options=dense_opt).max_acc_m_s2
    grid = make_grid(b, ONE_FORCE.length_m, speeds_to_m_s(speeds), opt)
    exact = np.array([exact_mlm_max(b, v / 3.6, grid.n_steps * dt) for v, dt in zip(speeds, grid.dt_s)])
    # the step error: RK4's midspan acceleration at the nodes against the closed form
    step_err = np.empty(speeds.size)
    for i, v in enumerate(speeds):
        q, qd, f = moving_force_modal(b, 100e3, v / 3.6, r.time_s[i])
        a = f[0] - 2 * b.modal_damping_ratios(0.0)[0] * b.omega_rad_s[0] * qd[0] - b.omega_rad_s[0] ** 2 * q[0]
        step_err[i] = np.abs(r.midspan_acc_m_s2[i] - a).max() / np.abs(a).max()
    err_dense, err_sampled = np.abs(dense / exact - 1), np.abs(sampled / exact - 1)
    # one mode at 16 steps per period (150 km/h): step error 4e-4 .. 4e-3; the sampled maximum
    # misses by up to 1 - cos(pi / 16) = 1.9 %, the dense one by no more than the step error
    assert np.all(err_dense <= step_err)
    assert err_sampled.max() > 10 * err_dense.max()
    assert np.all(dense >= sampled)
    # the compiled batch gives the same numbers
    r = BatchRunner([b], ONE_FORCE, grid.ds_m, dense_maxima=True)
    np.testing.assert_allclose(r.run("mlm", np.zeros(5, int), speeds)[0], dense, rtol=1e-12)


# ---------------------------------------------------------------------- DIM, fine-step reference
@pytest.mark.slow
def test_dim_dense_maxima_against_fine_step_and_numpy_equals_kernels():
    b, t = named_bridge("B1"), load_train("ICE-2")
    speeds = np.array([200.0, 240.0, 300.0])
    grid = make_grid(b, t.length_m, speeds_to_m_s(speeds), StepOptions())
    case = np.zeros(3, int)
    # numpy stepper and compiled kernels, one to one
    dense = run_sweep(b, t, "dim", speeds, options=StepOptions(ds_m=grid.ds_m, dense_maxima=True)).max_acc_m_s2
    got = BatchRunner([b], t, grid.ds_m, dense_maxima=True).run("dim", case, speeds)[0]
    # the states agree to ~1e-15 (a few dot products summed in another order); the Hermite quintic
    # divides displacement differences by h^2, which lifts that to ~1e-12 in the dense maximum
    # (measured 1.05e-12 at 200 km/h): 5e-12 is round-off, a wrong term shows at 1e-6 and above
    np.testing.assert_allclose(got, dense, rtol=5e-12)

    def run(factor, dense):
        return BatchRunner([b], t, grid.ds_m / factor, dense_maxima=dense).run("dim", case, speeds)[0]

    ref = run(8, True)
    assert np.abs(run(8, False) / ref - 1).max() <= 1e-4   # the reference itself: sampled ~ dense
    for factor in (1, 2):
        sampled, dense = run(factor, False), run(factor, True)
        assert np.all(dense >= sampled)
        err_s, err_d = np.abs(sampled / ref - 1).max(), np.abs(dense / ref - 1).max()
        # measured: default step 2.2e-3 sampled vs 8.7e-4 dense; half step 4.5e-4 vs 1.9e-4
        assert err_d < 0.5 * err_s and err_d <= (1.5e-3 if factor == 1 else 3e-4)
