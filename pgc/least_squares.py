"""Levenberg-Marquardt for small dense nonlinear least squares (a few parameters, many residuals)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

MAX_DAMPING = 1e8
"""Damping beyond which no descent step is searched for: the point is a minimum to the solver's precision."""


@dataclass
class LeastSquaresResult:
    x: np.ndarray
    cost: float
    """The cost at ``x``: ``|residual(x)|^2`` (``r_a . r_b`` for two estimates)."""
    initial_cost: float
    """The cost at ``x0``."""
    iterations: int
    """Jacobians evaluated."""
    stopped: str
    """'converged' (the step at the initial damping below the tolerance), 'no_descent' (no damping found a lower
    cost) or 'iterations' (the bound)."""


def levenberg_marquardt(residual: Callable[[np.ndarray], np.ndarray],
                        jacobian: Callable[[np.ndarray, np.ndarray], np.ndarray], x0: np.ndarray,
                        project: Callable[[np.ndarray], np.ndarray] = lambda x: x, iterations: int = 30,
                        step_tolerance: float = 0.0, damping: float = 1e-3) -> LeastSquaresResult:
    """Minimise ``|residual(x)|^2`` from ``x0``. ``jacobian(x, residual(x))`` gives d residual / dx (rows:
    residuals). Each step solves ``(J^T J + damping diag(J^T J)) dx = -J^T r`` (Marquardt's scaling), then
    ``project`` maps the trial point into the feasible set (e.g. clamps to bounds); a trial that lowers the cost
    is accepted and the damping divided by 3, else the damping is multiplied by 4 and the step solved again.
    Stops after ``iterations`` Jacobians, when the damping exceeds :data:`MAX_DAMPING`, or once a step is accepted
    from a point where the step at the initial damping moves no coordinate more than ``step_tolerance``. The
    test is on that step, not on the accepted one: a step shortened by a raised damping is small because the
    trust region shrank, not because the point is a minimum (on a slope where long steps fail, as they do along
    a noisy Jacobian's wrong direction, the accepted steps are tiny far from the minimum).

    Noisy residuals (Monte Carlo renders): ``residual`` may return two independent estimates ``(2, n)`` of the
    same expected residuals, and ``jacobian`` their Jacobians ``(2, n, p)``. The cost is then ``r_a . r_b``,
    whose expectation is ``|E r|^2``; ``|r_a|^2`` would add the estimates' variance, which depends on ``x``
    and moves the minimum toward parameters that render with less noise. The step uses the gradient
    ``(J_a^T r_b + J_b^T r_a) / 2`` and, for ``J^T J``, ``(J_a^T J_b + J_b^T J_a) / 2`` with its eigenvalues
    raised to at least 1e-9 of the largest: ``J_a^T J_a`` would add the Jacobian's own noise to the curvature,
    which shortens the steps along weakly determined directions to a crawl."""
    x = np.asarray(x0, np.float64).copy()
    initial_damping = damping
    r = residual(x)
    cost = initial = _cost(r)
    for iteration in range(1, iterations + 1):
        J = jacobian(x, r)
        Ja, Jb = (J, J) if J.ndim == 2 else J
        ra, rb = (r, r) if r.ndim == 1 else r
        JtJ, Jtr = _normal_matrix(Ja, Jb), (_dot(Ja, rb) + _dot(Jb, ra)) / 2.0
        stationary = float(np.abs(_step(x, JtJ, Jtr, initial_damping, project) - x).max()) <= step_tolerance
        while True:
            trial = _step(x, JtJ, Jtr, damping, project)
            r_trial = residual(trial)
            trial_cost = _cost(r_trial)
            if trial_cost < cost:
                x, r, cost, damping = trial, r_trial, trial_cost, max(damping / 3.0, 1e-9)
                break
            damping *= 4.0
            if damping > MAX_DAMPING:
                return LeastSquaresResult(x, cost, initial, iteration, "no_descent")
        if stationary:
            return LeastSquaresResult(x, cost, initial, iteration, "converged")
    return LeastSquaresResult(x, cost, initial, iterations, "iterations")


def _step(x: np.ndarray, JtJ: np.ndarray, Jtr: np.ndarray, damping: float,
          project: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """The projected point of the step with Marquardt's scaled ``damping`` from ``x``."""
    return project(x - np.linalg.solve(JtJ + damping * np.diag(np.diag(JtJ) + 1e-12), Jtr))


def _cost(r: np.ndarray) -> float:
    """``|r|^2``, or ``r_a . r_b`` for two estimates."""
    return float(r @ r) if r.ndim == 1 else float(r[0] @ r[1])


def _normal_matrix(Ja: np.ndarray, Jb: np.ndarray) -> np.ndarray:
    """``J^T J`` for one Jacobian; for two independent estimates, their symmetrised cross product made
    positive definite, also when noise leaves no positive eigenvalue (see :func:`levenberg_marquardt`)."""
    if Ja is Jb:
        return _dot(Ja, Ja)
    w, v = np.linalg.eigh((_dot(Ja, Jb) + _dot(Jb, Ja)) / 2.0)
    return (v * np.maximum(w, 1e-9 * max(float(w.max()), np.finfo(float).tiny))) @ v.T


def _dot(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A^T B`` summed over the rows in a fixed order (numpy's own loops, not a multi-threaded BLAS whose
    partial sums depend on the thread count): the solver's result is the same bytes on any machine load."""
    return np.einsum("ij,i...->j...", A, B)
