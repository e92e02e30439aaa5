"""Loading a user's body motion: a folder of OBJ files (one per frame) or an ``.npz``.

npz keys: ``vertices`` (T, V, 3) metres, ``faces`` (F, 3) int, optional ``fps`` (scalar, default 30).
OBJ folder: files sorted by the number in their names (``frame_2.obj`` before ``frame_10.obj``), all with
the same topology (read by :func:`pgc.io.mesh.read_mesh`); the faces of the first file are used; ``fps``
is given by the caller.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.io.mesh import read_mesh
from pgc.types import BodyMotion


def _natural_key(path: Path) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name)]


def load_motion(path: str | Path, fps: float | None = None, name: str | None = None) -> BodyMotion:
    """A :class:`BodyMotion` from an ``.npz`` file or a folder of ``.obj`` frames.

    ``fps`` overrides the file's (npz) or sets the folder's (default 30). Errors name the file and the fix.
    """
    path = Path(path)
    name = name or path.stem
    if path.is_dir():
        files = sorted(path.glob("*.obj"), key=_natural_key)
        if not files:
            raise PGCDataError(f"{path}: no .obj files; a motion folder holds one OBJ per frame")
        frames, faces = [], None
        for f in files:
            mesh = read_mesh(f)
            v = mesh.vertices
            if faces is None:
                faces = mesh.faces
            elif v.shape[0] != frames[0].shape[0]:
                raise PGCDataError(f"{f}: {v.shape[0]} vertices, but {files[0].name} has {frames[0].shape[0]}; "
                                   "every frame must share one topology")
            frames.append(v)
        return BodyMotion(np.stack(frames), faces, float(fps or 30.0), name)
    if path.suffix.lower() != ".npz":
        raise PGCDataError(f"{path}: expected a folder of .obj frames or an .npz file")
    if not path.exists():
        raise PGCDataError(f"{path}: file not found")
    with np.load(path, allow_pickle=False) as data:
        for key in ("vertices", "faces"):
            if key not in data:
                raise PGCDataError(f"{path}: missing array '{key}' (need vertices (T, V, 3) and faces (F, 3))")
        vertices, faces = data["vertices"], data["faces"]
        file_fps = float(data["fps"]) if "fps" in data else 30.0
    if vertices.ndim != 3 or vertices.shape[2] != 3:
        raise PGCDataError(f"{path}: 'vertices' must be (T, V, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.size == 0:
        raise PGCDataError(f"{path}: 'faces' must be a non-empty (F, 3) array, got {faces.shape}")
    if faces.min() < 0 or faces.max() >= vertices.shape[1]:
        raise PGCDataError(f"{path}: 'faces' index out of range [0, {vertices.shape[1]})")
    return BodyMotion(vertices, faces, float(fps or file_fps), name)
