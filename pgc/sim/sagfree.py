"""Sag-free rest shape: rest lengths whose equilibrium under gravity on the capture body is the target.

The reconstructed garment is already a *loaded* shape: used as the rest shape, it sags further under
gravity (the paper's stated limitation). Inverse statics by fixed-point iteration on the rest lengths:

    L_{k+1} = L_k * (|e*| / |e_k|)   (per constraint, ratio clamped to [1/2, 2])

with ``|e*|`` the constraint lengths of the target (the reconstruction) and ``|e_k|`` those at the
equilibrium reached from the target with rest lengths ``L_k`` (the simulator itself settles the garment,
so its finite iterations, compliance, contacts and friction are all accounted for). Equilibrium positions
start at the target, so the solve keeps the garment where it was captured wherever the body supports it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from pgc.sim.model import ClothModel


def sag(positions: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """Mean and max vertex displacement (m) of ``positions`` from ``target``."""
    d = np.linalg.norm(positions - target, axis=1)
    return float(d.mean()), float(d.max())


def shape_error(positions: np.ndarray, target: np.ndarray) -> float:
    """Mean vertex displacement (m) of ``positions`` from ``target`` after removing the mean translation: the
    deformation part of the sag (a garment that drops rigidly into contact has none)."""
    d = positions - target
    return float(np.linalg.norm(d - d.mean(axis=0), axis=1).mean())


def hem_sag(positions: np.ndarray, target: np.ndarray, band: float = 0.02) -> float:
    """Mean downward (-y) displacement (m) of the hem: the target vertices within ``band`` (m) of its lowest."""
    hem = target[:, 1] < target[:, 1].min() + band
    return float(np.mean(target[hem, 1] - positions[hem, 1]))


def solve_sag_free(model: ClothModel, equilibrium: Callable[[ClothModel], np.ndarray], iterations: int,
                   progress: Callable[..., Any] | None = None) -> tuple[ClothModel, list[dict[str, float]]]:
    """Rest lengths for which ``equilibrium(model)`` (positions after settling on the capture body,
    starting from ``model.rest_positions``) reproduces ``model.rest_positions``.

    Returns the model with the solved rest lengths (best iterate by mean sag) and the history of
    ``{"iteration", "sag_mean", "sag_max", "shape_error", "drop", "hem_sag", "length_error"}`` (m; ``drop``:
    the mean downward displacement); iteration 0 is the plain rest shape.
    """
    target = model.rest_positions
    goal = np.linalg.norm(target[model.ci] - target[model.cj], axis=1)
    best, best_sag, history = model, np.inf, []
    current = model
    for it in range(iterations + 1):
        x = equilibrium(current)
        lengths = np.linalg.norm(x[model.ci] - x[model.cj], axis=1)
        mean, worst = sag(x, target)
        history.append({"iteration": it, "sag_mean": mean, "sag_max": worst, "shape_error": shape_error(x, target),
                        "drop": float(target[:, 1].mean() - x[:, 1].mean()), "hem_sag": hem_sag(x, target),
                        "length_error": float(np.sqrt(np.mean((lengths - goal) ** 2)))})
        if progress is not None:
            progress(it, iterations, sag_mean=mean)
        if mean < best_sag:
            best, best_sag = current, mean
        if it == iterations:
            break
        ratio = np.clip(np.divide(goal, lengths, out=np.ones_like(goal), where=lengths > 1e-12), 0.5, 2.0)
        current = current.with_rest(current.rest * ratio)
    return best, history
