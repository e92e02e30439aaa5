"""The environment as radiance over a fixed set of directions (numpy).

Directions: a spherical Fibonacci set of n unit vectors, each standing for a cell of solid angle 4 pi / n.
A lat-long environment map (pgc.types.Light convention, Mitsuba's: +Y up, pixel column u from
``atan2(d.x, -d.z) / 2 pi``, row from ``acos(d.y) / pi``, rotated by ``rotation_deg`` about +Y) is
averaged over each cell (every map pixel, weighted by its solid angle, goes to its nearest direction).
"""

from __future__ import annotations

import numpy as np

from pgc.sampling import envmap_directions
from pgc.types import Light


def direction_radiance(light: Light, directions: np.ndarray) -> np.ndarray:
    """(n, 3) mean radiance of ``light`` over the cell of each direction."""
    radiance = np.asarray(light.radiance, dtype=np.float64)
    if light.envmap is None:
        return np.broadcast_to(radiance, (len(directions), 3)).copy()
    env = np.asarray(light.envmap, dtype=np.float64)
    dirs, solid = envmap_directions(env.shape[0], env.shape[1], light.rotation_deg)
    nearest = np.empty(len(dirs), dtype=np.int64)
    for s in range(0, len(dirs), 8192):
        nearest[s:s + 8192] = np.argmax(dirs[s:s + 8192] @ directions.T, axis=1)
    weight = np.bincount(nearest, weights=solid, minlength=len(directions))
    total = np.stack([np.bincount(nearest, weights=solid * env.reshape(-1, 3)[:, c], minlength=len(directions))
                      for c in range(3)], axis=1)
    mean = np.divide(total, weight[:, None], out=np.zeros_like(total), where=weight[:, None] > 0)
    empty = weight == 0
    if empty.any():  # cells finer than the map: take the map value at the direction itself
        mean[empty] = _lookup(env, directions[empty], light.rotation_deg)
    return mean * radiance


def _lookup(env: np.ndarray, d: np.ndarray, rotation_deg: float) -> np.ndarray:
    a = np.radians(rotation_deg)
    rot = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    local = d @ rot
    u = (np.arctan2(local[:, 0], -local[:, 2]) / (2 * np.pi)) % 1.0
    v = np.arccos(np.clip(local[:, 1], -1.0, 1.0)) / np.pi
    h, w = env.shape[:2]
    return env[np.minimum((v * h).astype(int), h - 1), np.minimum((u * w).astype(int), w - 1)]
