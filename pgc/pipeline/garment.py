"""The Gaussians that belong to the garment sub-mesh (faces chosen by pgc.geometry.garment)."""

from __future__ import annotations

import numpy as np

from pgc.types import GaussianSet


def garment_gaussians(gaussians: GaussianSet, face_selection: np.ndarray) -> GaussianSet:
    """The Gaussians bound to selected faces, with parents renumbered to the sub-mesh's face order."""
    new_index = np.full(len(face_selection), -1, dtype=np.int64)
    new_index[face_selection] = np.arange(int(face_selection.sum()))
    kept = gaussians.select(face_selection[gaussians.parent])
    kept.parent = new_index[kept.parent]
    return kept
