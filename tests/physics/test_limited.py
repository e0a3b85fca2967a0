"""The exact solution with a current-limited driver (and the regime-switching solution
Coulomb friction needs when the voltage reverses): against an independent fine ODE
integration of the clamped motor, its derivatives against finite differences, and the
angle against a quadrature of the speed."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pmdc_bayes._x64 import x64
from pmdc_bayes.inference.model.nuisances import NO_LIMIT
from pmdc_bayes.physics.angle import since_first_sample
from pmdc_bayes.physics.solution import Params, make_experiment, simulate_padded

# the tests call the physics directly, as the package calls it inside its 64-bit context
pytestmark = pytest.mark.usefixtures("jax_x64")

P = Params(Ra=2.0, La=2e-3, K=0.05, B=2e-5, J=2e-5, Tc=2e-3)
T = np.linspace(0.0, 1.5, 1501)
# Up from rest, then reversed: the rotor is clamped on the way up, braked against the
# limit, stopped and driven back.
SCHEDULE = (np.array([0.0, 0.1, 0.8]), np.array([0.0, 12.0, -6.0]))
LIMIT = 1.5


def _ode(limit, coulomb, t=T):
    """The motor with a driver that holds |ia| at ``limit`` while the commanded voltage
    pushes past it, Coulomb friction with stiction, by LSODA at tight tolerances; rows
    ``(ia, ω, angle)``."""
    tc = P.Tc if coulomb else 0.0

    def f(_, x, va):
        ia, w, _ = x
        clamped = abs(ia) >= limit and np.sign(ia) * (va - P.Ra * ia - P.K * w) > 0
        dia = 0.0 if clamped else (va - P.Ra * ia - P.K * w) / P.La
        drive = P.K * ia
        if coulomb and abs(w) < 1e-9 and abs(drive) <= tc:
            return [dia, 0.0, 0.0]
        direction = np.sign(w) if abs(w) >= 1e-9 else np.sign(drive)
        return [dia, (drive - P.B * w - tc * direction) / P.J, w]

    out, x = np.zeros((3, t.size)), [0.0, 0.0, 0.0]
    edges = list(SCHEDULE[0]) + [t[-1]]
    for lo, hi, va in zip(edges[:-1], edges[1:], SCHEDULE[1], strict=True):
        sel = (t >= lo) & (t <= hi)
        sol = solve_ivp(f, (lo, hi), x, t_eval=t[sel], args=(va,), method="LSODA",
                        rtol=1e-10, atol=[1e-12, 1e-12, 1e-10], max_step=1e-4)
        out[:, sel] = sol.y
        x = sol.y[:, -1]
    return out


def _exact(p, limit, coulomb, t=T):
    exp = make_experiment(t, *SCHEDULE)
    ia, w = simulate_padded(p, exp, coulomb=coulomb, limit=limit)
    return exp, exp.unpad(ia), exp.unpad(w)


@pytest.mark.parametrize("coulomb", [False, True])
def test_the_clamped_motor_matches_a_fine_ode(coulomb):
    _, ia, w = _exact(P, jnp.asarray(LIMIT), coulomb)
    ref = _ode(LIMIT, coulomb)
    assert np.max(np.abs(ia)) == pytest.approx(LIMIT, rel=1e-12)  # it does clamp
    assert np.max(np.abs(np.asarray(ia) - ref[0])) < 1e-7 * LIMIT
    assert np.max(np.abs(np.asarray(w) - ref[1])) < 1e-8 * np.max(np.abs(ref[1]))


def test_coulomb_friction_reverses_the_rotor_within_a_segment():
    """Without a limit, the regime-switching solution stops the rotor and drives it back
    when the voltage reverses (the stop-and-stay solution would hold it at rest)."""
    _, _, w = _exact(P, NO_LIMIT, True)
    ref = _ode(np.inf, True)
    assert ref[1][-1] < -50.0
    assert np.max(np.abs(np.asarray(w) - ref[1])) < 1e-8 * np.max(np.abs(ref[1]))


def test_a_limit_never_reached_leaves_the_exact_solution_unchanged():
    exp = make_experiment(T, np.array([0.0, 0.2]), np.array([5.0, 9.0]), initial="steady")
    ia0, w0 = simulate_padded(P, exp)
    ia1, w1 = simulate_padded(P, exp, limit=NO_LIMIT)
    assert np.max(np.abs(np.asarray(w1 - w0))) < 1e-10 * float(jnp.max(jnp.abs(w0)))
    assert np.max(np.abs(np.asarray(ia1 - ia0))) < 1e-10 * float(jnp.max(jnp.abs(ia0)))


@pytest.mark.compiles
@pytest.mark.parametrize("coulomb", [False, True])
def test_derivatives_through_the_located_switching_times(coulomb):
    """Forward- and reverse-mode derivatives of a fit-like sum over the samples with
    respect to K, J, B and the limit agree with central differences: the clamp's entry
    and exit times carry their dependence on the parameters."""
    def total(x):
        p = P._replace(K=x[0], J=x[1], B=x[2])
        _, ia, w = _exact(p, x[3], coulomb)
        return jnp.sum(w) * 1e-3 + jnp.sum(ia)

    x0 = jnp.array([P.K, P.J, P.B, LIMIT])
    fwd = np.asarray(jax.jacfwd(total)(x0))
    rev = np.asarray(jax.grad(total)(x0))
    fd = []
    for k in range(4):
        h = 1e-6 * float(x0[k])
        e = jnp.zeros(4).at[k].set(h)
        fd.append((float(total(x0 + e)) - float(total(x0 - e))) / (2 * h))
    assert np.all(np.isfinite(fwd)) and np.all(np.isfinite(rev))
    np.testing.assert_allclose(fwd, fd, rtol=1e-4)
    np.testing.assert_allclose(rev, fwd, rtol=1e-9)


def test_the_angle_through_the_clamp_matches_a_fine_ode():
    """The angle at 10 ms samples, entering, holding and leaving the clamp, stopped and
    driven back by friction, against the angle integrated with the fine ODE: exact, not
    a quadrature of the samples (which misses ~1e-4 rad in an interval where the
    current races to the limit)."""
    t = np.linspace(0.0, 1.5, 151)
    exp = make_experiment(t, *SCHEDULE)
    _, _, angle = simulate_padded(P, exp, coulomb=True, limit=jnp.asarray(LIMIT),
                                  with_angle=True)
    start = jnp.asarray(np.arange(t.size) == 0)
    theta = np.asarray(since_first_sample(exp, angle, start))
    ref = _ode(LIMIT, True, t)[2]
    travel = np.max(np.abs(ref))
    assert travel > 50.0
    assert np.max(np.abs(theta - ref)) < 1e-8 * travel


@pytest.mark.parametrize("limit", [None, 1e200])
def test_a_load_that_overcomes_the_friction_moves_a_rotor_at_rest_its_way(limit):
    """At rest with no current, a load of −0.01 N·m (driving forward) beats Tc = 3 mN·m:
    the rotor starts forward at once, although the voltage (−2 V) will pull it back;
    against the same motion integrated by SciPy until it stops."""
    ra, la, k, b, j, tc, tl, v = 2.0, 2e-3, 0.05, 2e-4, 2e-5, 3e-3, -0.01, -2.0
    t = np.arange(0.0, 3.5e-4, 5e-5)
    exp = make_experiment(t, [0.0], [v], [0.0], [tl])
    _, w = x64(simulate_padded)(Params(ra, la, k, b, j, tc), exp, coulomb=True, limit=limit)
    w = np.asarray(exp.unpad(w))

    def forward(_, x):  # moving forward, friction −Tc
        return [(v - ra * x[0] - k * x[1]) / la, (k * x[0] - b * x[1] - tl - tc) / j]

    ref = solve_ivp(forward, (0.0, t[-1]), [0.0, 0.0], t_eval=t, rtol=1e-12, atol=1e-15).y[1]
    assert np.all(ref[1:] > 0)  # (the reference still moves forward over these samples)
    np.testing.assert_allclose(w, ref, atol=1e-6 * ref.max())
