"""Levenberg-Marquardt (pgc.least_squares) on small exact problems."""

from __future__ import annotations

import numpy as np

from pgc.least_squares import levenberg_marquardt

T = np.linspace(0.0, 2.0, 40)


def residual(x: np.ndarray) -> np.ndarray:
    """A decaying exponential plus a constant, against its values at (2, 1.5, 0.3)."""
    return x[0] * np.exp(-x[1] * T) + x[2] - (2.0 * np.exp(-1.5 * T) + 0.3)


def jacobian(x: np.ndarray, r: np.ndarray) -> np.ndarray:
    e = np.exp(-x[1] * T)
    return np.stack([e, -x[0] * T * e, np.ones_like(T)], 1)


def test_converges_to_the_exact_minimum_and_stops_on_the_step_tolerance() -> None:
    result = levenberg_marquardt(residual, jacobian, np.array([0.5, 0.2, 0.0]), iterations=100,
                                 step_tolerance=1e-10)
    np.testing.assert_allclose(result.x, [2.0, 1.5, 0.3], atol=1e-8)
    assert result.stopped in ("converged", "no_descent") and result.iterations < 100
    assert result.cost < 1e-20 < result.initial_cost


def test_projection_holds_a_bound_and_the_bound_is_bounded_in_iterations() -> None:
    """With the constant clamped to at most 0.1 the fit ends on the bound; one Jacobian only: 'iterations'."""
    result = levenberg_marquardt(residual, jacobian, np.array([0.5, 0.2, 0.0]),
                                 project=lambda x: np.minimum(x, [np.inf, np.inf, 0.1]), iterations=60)
    assert result.x[2] == 0.1 and result.cost < result.initial_cost
    one = levenberg_marquardt(residual, jacobian, np.array([0.5, 0.2, 0.0]), iterations=1)
    assert one.iterations == 1 and one.stopped == "iterations"


def test_two_estimates_remove_the_bias_of_a_parameter_dependent_noise() -> None:
    """Residuals with Monte Carlo-like noise whose size grows with the decay rate x[1] (two fixed noise draws,
    as two seeds): the squares of one draw pull the fit toward a low-noise rate; the product of the two does
    not, and the cross-product normal matrix keeps the steps long enough to get there."""
    rng = np.random.default_rng(0)
    eps = rng.normal(size=(2, T.size))

    def noisy(x: np.ndarray) -> np.ndarray:
        return residual(np.append(x, 0.3)) + 0.2 * x[1] * eps

    def noisy_jacobian(x: np.ndarray, r: np.ndarray) -> np.ndarray:
        clean = jacobian(np.append(x, 0.3), r)[:, :2]
        return np.stack([clean + np.stack([np.zeros(T.size), 0.2 * e], 1) for e in eps])

    start = np.array([1.0, 0.5])
    both = levenberg_marquardt(noisy, noisy_jacobian, start, iterations=50, step_tolerance=1e-9)
    one = levenberg_marquardt(lambda x: noisy(x)[0], lambda x, r: noisy_jacobian(x, r)[0], start, iterations=50,
                              step_tolerance=1e-9)
    assert np.abs(both.x / [2.0, 1.5] - 1.0).max() < 0.05, both
    assert np.abs(one.x / [2.0, 1.5] - 1.0).max() > 0.2, one


def test_a_step_shortened_by_raised_damping_is_not_convergence() -> None:
    """``r(x) = x - x*`` with a Jacobian rotated by 89.9 degrees (a noisy Jacobian's worst case): only steps
    shorter than about ``|r| / 286`` lower the cost, so the damping must rise before any step is accepted, and
    that step is below the tolerance 0.1 away from the minimum. Stopping there as 'converged' would report a
    slope as a minimum; the solver must go on, and every step it takes lowers the distance to x*."""
    target = np.array([1.0, -2.0])
    angle = np.radians(89.9)
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    start = target + np.array([0.1, 0.0])
    result = levenberg_marquardt(lambda x: x - target, lambda x, r: rotation, start, iterations=40,
                                 step_tolerance=1e-3)
    assert result.stopped == "iterations" and np.linalg.norm(result.x - target) > 0.09, result
    assert np.linalg.norm(result.x - target) < np.linalg.norm(start - target)
    assert result.cost < result.initial_cost
    exact = levenberg_marquardt(lambda x: x - target, lambda x, r: np.eye(2), start, iterations=40,
                                step_tolerance=1e-3)
    assert exact.stopped == "converged" and np.linalg.norm(exact.x - target) < 1e-3, exact
