"""Evenly spread subsets (of views, cameras, frames) and directions. Light module."""

from __future__ import annotations

from typing import Sequence, TypeVar

import numpy as np

T = TypeVar("T")


def spread(items: Sequence[T], count: int) -> list[T]:
    """``count`` items evenly spread over ``items``, first and last included (all when there are fewer)."""
    if count >= len(items):
        return list(items)
    return [items[int(i)] for i in np.linspace(0, len(items) - 1, count).round().astype(int)]


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (+Y the polar axis)."""
    k = np.arange(n) + 0.5
    y = 1.0 - 2.0 * k / n
    r = np.sqrt(np.maximum(1.0 - y * y, 0.0))
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    return np.stack([r * np.cos(phi), y, r * np.sin(phi)], axis=1)


def envmap_directions(height: int, width: int, rotation_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """World directions (H*W, 3) of the pixel centres of a lat-long map and their solid angles (H*W,)."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    U, Vv = np.meshgrid(u, v)
    phi, theta = 2 * np.pi * U, np.pi * Vv
    # local: atan2(x, -z) = phi, acos(y) = theta
    local = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], -1).reshape(-1, 3)
    a = np.radians(rotation_deg)
    rot = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    solid = (np.sin(theta) * (np.pi / height) * (2 * np.pi / width)).reshape(-1)
    return local @ rot.T, solid
