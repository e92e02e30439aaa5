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
    """``|residual(x)|^2``."""
    initial_cost: float
    """``|residual(x0)|^2``."""
    iterations: int
    """Jacobians evaluated."""
    stopped: str
    """'converged' (an accepted step below the tolerance), 'no_descent' (no damping found a lower cost) or
    'iterations' (the bound)."""


def levenberg_marquardt(residual: Callable[[np.ndarray], np.ndarray],
                        jacobian: Callable[[np.ndarray, np.ndarray], np.ndarray], x0: np.ndarray,
                        project: Callable[[np.ndarray], np.ndarray] = lambda x: x, iterations: int = 30,
                        step_tolerance: float = 0.0, damping: float = 1e-3) -> LeastSquaresResult:
    """Minimise ``|residual(x)|^2`` from ``x0``. ``jacobian(x, residual(x))`` gives d residual / dx (rows:
    residuals). Each step solves ``(J^T J + damping diag(J^T J)) dx = -J^T r`` (Marquardt's scaling), then
    ``project`` maps the trial point into the feasible set (e.g. clamps to bounds); a trial that lowers the cost
    is accepted and the damping divided by 3, else the damping is multiplied by 4 and the step solved again.
    Stops after ``iterations`` Jacobians, once an accepted step moves no coordinate more than
    ``step_tolerance``, or when the damping exceeds :data:`MAX_DAMPING`."""
    x = np.asarray(x0, np.float64).copy()
    r = residual(x)
    cost = initial = float(r @ r)
    for iteration in range(1, iterations + 1):
        J = jacobian(x, r)
        JtJ, Jtr = J.T @ J, J.T @ r
        while True:
            trial = project(x - np.linalg.solve(JtJ + damping * np.diag(np.diag(JtJ) + 1e-12), Jtr))
            r_trial = residual(trial)
            trial_cost = float(r_trial @ r_trial)
            if trial_cost < cost:
                moved = float(np.abs(trial - x).max())
                x, r, cost, damping = trial, r_trial, trial_cost, max(damping / 3.0, 1e-9)
                break
            damping *= 4.0
            if damping > MAX_DAMPING:
                return LeastSquaresResult(x, cost, initial, iteration, "no_descent")
        if moved <= step_tolerance:
            return LeastSquaresResult(x, cost, initial, iteration, "converged")
    return LeastSquaresResult(x, cost, initial, iterations, "iterations")
