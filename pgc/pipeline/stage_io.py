"""Exact, dependency-free storage of intermediate stage results (npz + json) inside the stage cache."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pgc.io.atomic import atomic_path
from pgc.types import GaussianSet, Mesh


def save_npz(path: Path, **arrays: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        np.savez(tmp, **arrays)


def save_mesh(path: Path, mesh: Mesh) -> None:
    arrays = {"vertices": mesh.vertices, "faces": mesh.faces}
    if mesh.uv is not None:
        arrays.update(uv=mesh.uv, face_uv=mesh.face_uv)
    if mesh.face_labels is not None:
        arrays["face_labels"] = mesh.face_labels
    save_npz(path, name=np.array(mesh.name), **arrays)


def load_mesh(path: Path) -> Mesh:
    with np.load(path) as z:
        return Mesh(z["vertices"], z["faces"], z["uv"] if "uv" in z else None,
                    z["face_uv"] if "face_uv" in z else None,
                    z["face_labels"] if "face_labels" in z else None, str(z["name"]))


def save_gaussians(path: Path, g: GaussianSet) -> None:
    save_npz(path, parent=g.parent, means=g.means, quats=g.quats, log_scales=g.log_scales,
             opacity_logits=g.opacity_logits, sh=g.sh)


def load_gaussians(path: Path) -> GaussianSet:
    with np.load(path) as z:
        return GaussianSet(z["parent"], z["means"], z["quats"], z["log_scales"], z["opacity_logits"], z["sh"])
