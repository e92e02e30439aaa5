"""The garment part of the full reconstruction: its Gaussians, and the rest of the body as an occluder."""

from __future__ import annotations

import numpy as np

from pgc.types import BACKGROUND_LABEL, BODY_LABEL, GARMENT_LABEL, GaussianSet, Mesh


def garment_gaussians(gaussians: GaussianSet, face_selection: np.ndarray) -> GaussianSet:
    """The Gaussians bound to selected faces, with parents renumbered to the sub-mesh's face order."""
    new_index = np.full(len(face_selection), -1, dtype=np.int64)
    new_index[face_selection] = np.arange(int(face_selection.sum()))
    kept = gaussians.select(face_selection[gaussians.parent])
    kept.parent = new_index[kept.parent]
    return kept


def body_occluder(full: Mesh, garment_ids: list[int]) -> Mesh | None:
    """The faces of ``full`` that are neither garment nor background (the body), or None if there are none."""
    if full.face_labels is None:
        return None
    keep = ~np.isin(full.face_labels, list(garment_ids) + [BACKGROUND_LABEL])
    return full.submesh(keep, name="body")[0] if keep.any() else None


def with_occluder(garment: Mesh, occluder: Mesh | None) -> Mesh:
    """One labelled mesh: the garment (its faces, labels and UV atlas) followed by the occluder faces,
    labelled body and mapped to a single dummy UV, for renderers that split garment and occluder by label."""
    if occluder is None:
        return garment
    nv, nuv = len(garment.vertices), len(garment.uv)
    labels = garment.face_labels if garment.face_labels is not None \
        else np.full(len(garment.faces), GARMENT_LABEL, np.int32)
    return Mesh(np.concatenate([garment.vertices, occluder.vertices]),
                np.concatenate([garment.faces, occluder.faces + nv]),
                np.concatenate([garment.uv, np.zeros((1, 2), np.float32)]),
                np.concatenate([garment.face_uv, np.full(occluder.faces.shape, nuv, np.int64)]),
                np.concatenate([labels, np.full(len(occluder.faces), BODY_LABEL, np.int32)]), name=garment.name)
