"""The exact model path against independent references.

Tolerances: the exact path is closed form in float64, so its agreement with another
exact formulation (expm steps, the steady state, a transfer function) is limited only
by rounding, ~1e-12 relative after a few thousand operations; we allow 1e-9.
Integrators are compared at their own tolerance (rtol 1e-10/1e-12) with margin: 1e-6.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import signal
from scipy.integrate import solve_ivp

from pmdc_bayes.physics.motor import gain, state_space, tf_full, time_constant
from pmdc_bayes.physics.motor import steady_state as steady_state_18
from pmdc_bayes.physics.ode import simulate_ode, simulate_scan
from pmdc_bayes.physics.solution import (
    Params,
    make_experiment,
    real_modes,
    simulate,
    simulate_padded,
    steady_state,
)

# the tests call the physics directly, as the package calls it inside its 64-bit context
pytestmark = pytest.mark.usefixtures("jax_x64")

P = Params(8.5, 5.621e-3, 0.062, 5.663e-5, 5.902e-4, 0.0)
PC = P._replace(Tc=2.5e-3)


def _step_load_experiment(dt=0.01, T=25.0):
    t = np.arange(0.0, T, dt)
    return make_experiment(t, [0.0, 0.5], [0.0, 12.97], [0.0, T / 2], [0.0, 0.01])


def _rhs(p, exp, coulomb):
    seg_t0 = np.asarray(exp.seg_t0)
    va_v, tl_v = np.asarray(exp.seg_va), np.asarray(exp.seg_tl)

    def f(t, y):
        k = max(np.searchsorted(seg_t0, t, side="right") - 1, 0)
        ia, w = y
        net = p.K * ia - tl_v[k] - p.B * w
        fr = 0.0
        if coulomb:
            fr = p.Tc * np.sign(w) if w != 0.0 else np.clip(net, -p.Tc, p.Tc)
        return [(va_v[k] - p.Ra * ia - p.K * w) / p.La, (net - fr) / p.J]

    return f


def _radau(p, exp, coulomb=False, y0=(0.0, 0.0)):
    """SciPy Radau, integrated segment by segment so no step straddles an input change."""
    t = exp.time
    bounds = list(np.asarray(exp.seg_t0)) + [t[-1]]
    ys, y = [], np.array(y0, dtype=float)
    f = _rhs(p, exp, coulomb)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        sel = (t >= a) & ((t < b) | (b == t[-1]))
        sol = solve_ivp(f, (a, b), y, method="Radau", rtol=1e-11, atol=1e-13,
                        t_eval=t[sel], dense_output=True)
        ys.append(sol.y)
        y = sol.sol(b)
    ys = np.concatenate(ys, axis=1)
    return ys[0], ys[1]


def test_steady_state_without_and_with_load():
    exp = _step_load_experiment(dt=0.05, T=100.0)
    ia, w = simulate(P, exp)
    # Just before the load step at 50 s, 40 mechanical time constants after the voltage step.
    k0 = int(np.searchsorted(exp.time, 49.9))
    i18, w17 = steady_state_18(P.Ra, P.K, P.B, 12.97)
    assert w17 == pytest.approx(P.K * 12.97 / (P.K**2 + P.Ra * P.B), rel=1e-15)
    np.testing.assert_allclose([w[k0], ia[k0]], [w17, i18], rtol=1e-9)
    il, wl = steady_state_18(P.Ra, P.K, P.B, 12.97, 0.01)
    np.testing.assert_allclose([w[-1], ia[-1]], [wl, il], rtol=1e-9)
    # The same via the state-space matrices (15)-(16).
    A, Bu, _, _ = state_space(P.Ra, P.La, P.K, P.B, P.J)
    x = -np.linalg.solve(A, Bu @ np.array([0.01, 12.97]))
    np.testing.assert_allclose([w[-1], ia[-1]], x, rtol=1e-9)


def test_first_order_limit_as_la_vanishes():
    p = P._replace(La=1e-7)
    t = np.linspace(0.0, 5.0, 501)
    ia, w = simulate(p, make_experiment(t, [0.0], [12.97]))
    tau = time_constant(P.Ra, P.K, P.B, P.J)
    G = gain(P.Ra, P.K, P.B)
    # La/Ra = 1.2e-8 s: the first-order model (8) is exact to O(La/Ra / tau) ~ 1e-8.
    np.testing.assert_allclose(w, G * 12.97 * (1.0 - np.exp(-t / tau)), rtol=1e-6, atol=1e-6)


def test_step_response_matches_transfer_function_7():
    num, den = tf_full(P.Ra, P.La, P.K, P.B, P.J)
    t = np.linspace(0.0, 4.0, 4001)
    _, y = signal.step(signal.lti(num, den), T=t)
    _, w = simulate(P, make_experiment(t, [0.0], [12.97]))
    np.testing.assert_allclose(w, 12.97 * y, rtol=1e-7, atol=1e-7 * 12.97 * y.max())


def test_against_scipy_radau_step_and_load_change():
    exp = _step_load_experiment()
    ia, w = simulate(P, exp)
    ri, rw = _radau(P, exp)
    np.testing.assert_allclose(w, rw, rtol=1e-6, atol=1e-6 * np.abs(rw).max())
    np.testing.assert_allclose(ia, ri, rtol=1e-6, atol=1e-6 * np.abs(ri).max())


def test_coulomb_breakaway_and_stop_against_scipy():
    t = np.arange(0.0, 12.0, 0.01)
    exp = make_experiment(t, [0.0, 0.5, 6.0], [0.0, 12.97, 0.0])
    ia, w = simulate(PC, exp, coulomb=True)
    # The rotor stays at rest until K·ia exceeds Tc, and coasts to a stop at 0 V.
    assert np.all(np.asarray(w)[t < 0.5] == 0.0)
    assert float(w[-1]) == 0.0 and float(w[650]) > 100.0
    ri, rw = _radau_with_stop(PC, exp)
    np.testing.assert_allclose(w, rw, rtol=1e-6, atol=1e-6 * np.abs(rw).max())
    np.testing.assert_allclose(ia, ri, rtol=1e-6, atol=1e-6 * np.abs(ri).max())


def _radau_with_stop(p, exp):
    """Radau per input segment; a stop is located as a terminal event, after which the
    rotor is held (dω = 0) and only the current is integrated.  Breakaway happens at a
    segment start from rest, where the stuck phase is integrated with dω = 0 until
    K·ia − TL reaches Tc (a second event)."""
    t = exp.time
    f = _rhs(p, exp, True)
    bounds = list(np.asarray(exp.seg_t0)) + [t[-1]]
    out = np.zeros((2, t.size))
    y = np.zeros(2)
    for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        tl = float(exp.seg_tl[k])
        phases = []
        start = a
        for _ in range(3):
            if start >= b:
                break
            moving = y[1] != 0.0
            if moving:
                direction = np.sign(y[1])

                def ev(_, yy):
                    return yy[1]

                def rhs(tt, yy, d=direction):  # smooth while it turns one way
                    dia, dw = f(tt, yy)
                    dw_viscous = dw + (p.Tc * np.sign(yy[1]) if yy[1] != 0.0 else 0.0) / p.J
                    return [dia, dw_viscous - d * p.Tc / p.J]
            else:
                def ev(_, yy, tl=tl):
                    return abs(p.K * yy[0] - tl) - p.Tc

                def rhs(tt, yy):
                    return [f(tt, [yy[0], 0.0])[0], 0.0]
            ev.terminal = True
            sol = solve_ivp(rhs, (start, b), y, method="Radau", rtol=1e-11, atol=1e-13,
                            dense_output=True, events=ev)
            phases.append((start, sol.t[-1], sol))
            y = sol.y[:, -1].copy()
            if sol.status == 1:
                if moving:
                    y[1] = 0.0
                else:
                    y[1] = 1e-300 * np.sign(p.K * y[0] - tl)
            start = sol.t[-1]
        for lo, hi, sol in phases:
            sel = (t >= lo) & ((t < hi) | (t == t[-1]) & (hi == t[-1]))
            if sel.any() and sol.t.size > 1:
                out[:, sel] = sol.sol(t[sel])
    return out[0], out[1]


def test_modal_path_matches_zoh_scan():
    exp = _step_load_experiment(dt=0.0025)
    ia, w = simulate(P, exp)
    si, sw = jax.jit(lambda p: simulate_scan(p, exp))(P)
    np.testing.assert_allclose(w, sw, rtol=1e-9, atol=1e-9 * float(jnp.abs(sw).max()))
    np.testing.assert_allclose(ia, si, rtol=1e-9, atol=1e-9 * float(jnp.abs(si).max()))


@pytest.mark.parametrize("coulomb", [False, True])
def test_diffrax_path_agrees_with_exact_path(coulomb):
    exp = _step_load_experiment()
    p = PC if coulomb else P
    ia, w = simulate(p, exp, coulomb=coulomb)
    oi, ow = jax.jit(lambda q: simulate_ode(q, exp, coulomb=coulomb))(p)
    np.testing.assert_allclose(ow, w, rtol=1e-6, atol=1e-6 * float(jnp.abs(w).max()))
    np.testing.assert_allclose(oi, ia, rtol=1e-6, atol=1e-6 * float(jnp.abs(ia).max()))


def test_irregular_sampling_diffrax_and_exact():
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 8.0, 300))
    exp = make_experiment(t, [0.0, 0.3], [2.0, 9.0], initial="steady")
    ia, w = simulate(P, exp)
    oi, ow = simulate_ode(P, exp)
    np.testing.assert_allclose(ow, w, rtol=1e-6, atol=1e-6 * float(jnp.abs(w).max()))


@pytest.mark.parametrize(
    "p",
    [
        Params(1.0, 5e-2, 0.05, 1e-5, 1e-5),  # slow current, light rotor: complex pair
        Params(2.0, 1e-3, 0.05, 1.0e-4, 2.0e-5),  # close to critical damping
    ],
)
def test_other_eigenvalue_regimes_match_expm(p):
    t = np.linspace(0.0, 0.2, 2001)
    exp = make_experiment(t, [0.0, 0.05], [0.0, 10.0], [0.0, 0.1], [0.0, 0.001])
    ia, w = simulate(p, exp)
    si, sw = jax.jit(lambda q: simulate_scan(q, exp))(p)
    np.testing.assert_allclose(w, sw, rtol=1e-8, atol=1e-8 * float(jnp.abs(sw).max()))
    np.testing.assert_allclose(ia, si, rtol=1e-8, atol=1e-8 * float(jnp.abs(si).max()))


def test_fast_real_path_equals_general_path():
    exp = _step_load_experiment()
    assert bool(real_modes(P))
    a = simulate_padded(P, exp)
    b = simulate_padded(P, exp, fast=True)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_initial_steady_state_step_from_5_to_15_volts():
    t = np.linspace(0.0, 10.0, 1001)
    exp = make_experiment(t, [0.0, 1.0], [5.0, 15.0], initial="steady")
    ia, w = simulate(P, exp)
    i5, w5 = steady_state(P, 5.0)
    np.testing.assert_allclose([ia[0], w[0]], [i5, w5], rtol=1e-12)
    np.testing.assert_allclose(w[:100], w5, rtol=1e-12)  # nothing moves before the step
    assert float(w[-1]) > 2.5 * float(w5)


@pytest.mark.parametrize("coulomb", [False, True])
def test_gradients_match_finite_differences(coulomb):
    exp = _step_load_experiment(dt=0.02, T=20.0)
    p0 = PC if coulomb else P
    ref_i, ref_w = simulate(p0, exp, coulomb=coulomb)
    names = Params._fields if coulomb else Params._fields[:5]
    log0 = jnp.log(jnp.array([getattr(p0, n) for n in names]))

    def loss(logp):
        vals = dict(zip(names, jnp.exp(logp), strict=True))
        q = p0._replace(**vals)
        ia, w = simulate(q, exp, coulomb=coulomb)
        return jnp.sum((w - 1.01 * ref_w) ** 2) + 1e4 * jnp.sum((ia - 0.99 * ref_i) ** 2)

    loss = jax.jit(loss)
    g = jax.grad(loss)(log0)
    for k in range(len(names)):
        h = 1e-6
        e = jnp.zeros_like(log0).at[k].set(h)
        fd = (loss(log0 + e) - loss(log0 - e)) / (2 * h)
        # Central differences: truncation O(h²) and rounding ~1e-16·loss/h; 1e-5 relative.
        assert float(g[k]) == pytest.approx(float(fd), rel=1e-5, abs=1e-8 * abs(float(loss(log0))))


def test_exact_path_compiles_once_for_same_shapes():
    traces = []

    def f(p, exp):
        traces.append(1)
        return simulate(p, exp)[1].sum()

    fj = jax.jit(f)
    t = np.arange(0.0, 5.0, 0.01)
    e1 = make_experiment(t, [0.0, 0.5], [0.0, 12.0])
    e2 = make_experiment(t, [0.0, 0.7], [0.0, 6.0])
    for p in (P, P._replace(K=0.07), P._replace(J=1e-3)):
        for e in (e1, e2):
            fj(p, e)
    assert len(traces) == 1
