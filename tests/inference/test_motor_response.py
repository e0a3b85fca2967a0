"""The motor's response coefficients as the sampler's coordinates, and the curvature the
coordinates are chosen by, where a ridge is too thin for differences to measure it."""

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from pmdc_bayes.inference.model.params import ParamSpec, Prior, Registry
from pmdc_bayes.inference.sampling.coordinates import exact_laplace
from pmdc_bayes.inference.sampling.motor_coordinates import MotorResponse
from pmdc_bayes.inference.sampling.stopping import Stop

sys.path.insert(0, str(Path(__file__).parent))
from fuzzed_posterior import sampled  # noqa: E402

MOTOR = dict(Ra=2.0, La=1e-3, K=0.05, B=2e-4, J=2e-5)


def _registry(offset_at=None):
    """The motor's parameters in log, with an offset (in value) at index ``offset_at``."""
    specs = [ParamSpec(n, "1", "motor", Prior("lognormal", v, 1.0), v) for n, v in MOTOR.items()]
    if offset_at is not None:
        specs.insert(offset_at, ParamSpec("offset", "1", "sensor", Prior("normal", 0.0, 1.0),
                                          0.0, transform="identity"))
    return Registry(specs)


def _coefficients(theta):
    """``(G, a₁, a₂)`` of equation (7) divided by its constant term, from θ ``(n, 5)``."""
    ra, la, k, b, j = (np.exp(theta[:, i]) for i in range(5))
    s = ra * b + k * k
    return k / s, (ra * j + la * b) / s, la * j / s


def test_the_motor_response_maps_back_and_carries_its_jacobian():
    """θ → φ → θ is the identity, an offset between the motor's parameters stays as it
    is, Coulomb friction moves as the steady speed it costs, the density's log-Jacobian
    is −log|det dφ/dθ| (differences), and a φ that is no motor (friction's share c of
    a₁ above a₁) maps to NaN."""
    xy = MotorResponse(_registry(offset_at=2))  # between La and K
    theta = np.log(np.array([[2.0, 1e-3, 1.0, 0.05, 2e-4, 2e-5],
                             [0.5, 3e-2, 1.0, 0.3, 1e-2, 1e-3]]))
    theta[:, 2] = [0.3, -1.0]
    np.testing.assert_allclose(xy.to_theta(xy.from_theta(theta)), theta, atol=1e-12)
    phi = xy.from_theta(theta)
    np.testing.assert_array_equal(phi[:, [0, 2]], theta[:, [0, 2]])
    g, a1, a2 = _coefficients(theta[:, [0, 1, 3, 4, 5]])
    np.testing.assert_allclose(np.exp(phi[:, [1, 3, 4]]), np.column_stack([g, a1, a2]),
                               rtol=1e-12)
    for t, lj in zip(theta, xy.log_jacobian(theta), strict=True):
        np.testing.assert_allclose(lj, -np.log(abs(np.linalg.det(xy.jacobian(t)))), rtol=1e-6)
    # with Coulomb friction, its torque moves as the steady speed it costs, Ra·Tc/S
    coulomb = Registry([*_registry().specs, ParamSpec("Tc", "1", "friction",
                                                      Prior("lognormal", 1e-3, 1.0), 1e-3)])
    xc = MotorResponse(coulomb)
    tc = np.column_stack([theta[:, [0, 1, 3, 4, 5]], np.log([1e-3, 4e-2])])
    np.testing.assert_allclose(xc.to_theta(xc.from_theta(tc)), tc, atol=1e-12)
    ra, s = np.exp(tc[:, 0]), np.exp(tc[:, 0] + tc[:, 3]) + np.exp(2 * tc[:, 2])
    np.testing.assert_allclose(np.exp(xc.from_theta(tc)[:, 5]), ra * np.exp(tc[:, 5]) / s,
                               rtol=1e-12)
    for t, lj in zip(tc, xc.log_jacobian(tc), strict=True):
        np.testing.assert_allclose(lj, -np.log(abs(np.linalg.det(xc.jacobian(t)))), rtol=1e-6)
    bad = phi[:1].copy()
    bad[0, 5] = bad[0, 3] + 0.1  # c above a₁
    assert np.all(np.isnan(xy.to_theta(bad)[0, [1, 3, 4, 5]]))


def _fine_step(theta):
    """A fine encoder's step without a current: the response's three coefficients each to
    a part in 10⁵, Ra and La from the bench (3 % and 10 %), K, B and J otherwise by their
    priors: a ridge a part in 10⁵ wide, curved in θ."""
    g, a1, a2 = _coefficients(theta)
    want = _coefficients(np.log(np.array([list(MOTOR.values())])))
    lp = stats.norm.logpdf(theta[:, 0], np.log(MOTOR["Ra"]), 0.03)
    lp += stats.norm.logpdf(np.exp(theta[:, 1]), MOTOR["La"], 0.1 * MOTOR["La"]) + theta[:, 1]
    for x, x0 in zip((g, a1, a2), want, strict=True):
        lp += stats.norm.logpdf(np.log(x), np.log(x0[0]), 1e-5)
    for i, n in ((2, "K"), (3, "B"), (4, "J")):
        lp += stats.norm.logpdf(theta[:, i], np.log(MOTOR[n]), 1.0)
    return lp


def _gauss_newton(theta):
    """The fit's curvature of :func:`_fine_step` at ``theta``: its residuals' Jacobian."""
    def residuals(t):
        g, a1, a2 = _coefficients(t[None])
        return np.concatenate([[(t[0] - np.log(2.0)) / 0.03],
                               [(np.exp(t[1]) - 1e-3) / 1e-4],
                               np.log(np.concatenate([g, a1, a2])) / 1e-5,
                               t[2:] / 1.0])
    h = 1e-7
    jac = np.column_stack([(residuals(theta + h * e) - residuals(theta - h * e)) / (2 * h)
                           for e in np.eye(5)])
    return np.linalg.inv(jac.T @ jac)


def test_a_ridge_too_thin_to_difference_keeps_the_fits_own_curvature():
    """Across a ridge a part in 10⁵ wide, steps of a thousandth of the Laplace sd along
    the ridge leave it: the differences measure its walls (curvatures 10⁴ times the
    fit's), and steps twice as long disagree, so the fit's own curvature is kept; on
    a Gaussian the differences are taken."""
    theta = np.log(np.array(list(MOTOR.values())))
    cov = _gauss_newton(theta)
    fit = type("Fit", (), {"theta": theta, "cov_log": 4.0 * cov, "cov_map": cov})()
    np.testing.assert_array_equal(exact_laplace(fit, _fine_step).cov_log, cov)
    sd = np.array([0.1, 0.2, 0.3, 0.4, 0.5])

    def gaussian(t):
        return stats.norm.logpdf(t, theta, sd).sum(1)
    wide = type("Fit", (), {"theta": theta, "cov_log": np.diag((2 * sd) ** 2)})()
    np.testing.assert_allclose(np.sqrt(np.diag(exact_laplace(wide, gaussian).cov_log)), sd,
                               rtol=1e-4)


@pytest.mark.compiles
def test_a_fine_encoders_step_is_sampled_in_the_motors_response(tmp_path):
    """Fuzzed session 154 (bench simulator; one step from rest read by a 4,096-count
    encoder for 1 s, no current, bench Ra and La): the posterior is a ridge about 10⁻⁷
    of its length wide along which K, B and J trade.  Sampled in θ (after differences
    too long for it had shrunk the Laplace approximation to its walls) the walkers sat
    in a corner, K's sd 0.001 against 0.25, and gave up after 8,650 steps; in the
    response's coefficients τ is a few steps, the gates pass, and every motor
    parameter's truth lies inside its 99 % interval."""
    fz, _, post, (ok, failures) = sampled(154, tmp_path)
    assert post.idata.posterior.attrs["coordinates"] == "motor response"
    assert post.stop is Stop.CONVERGED, post.message
    assert ok, failures
    draws = post.draws_si()
    assert np.std(np.log(draws["K"])) > 0.1  # K spreads along the ridge, as its Laplace sd
    for name in ("Ra", "La", "K", "B", "J"):
        lo, hi = np.quantile(draws[name], [0.005, 0.995])
        assert lo < fz.truth[name] < hi, (name, lo, fz.truth[name], hi)
