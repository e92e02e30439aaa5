"""Loading a user's body motion: a folder of OBJ files (one per frame) or an ``.npz``.

npz keys: ``vertices`` (T, V, 3) metres, ``faces`` (F, 3) int, optional ``fps`` (scalar, default 30).
OBJ folder: files sorted by the number in their names (``frame_2.obj`` before ``frame_10.obj``), all with
the same topology (read by :func:`pgc.io.mesh.read_mesh`); the faces of the first file are used; ``fps``
is given by the caller.
"""

from __future__ import annotations

import math
import re
import zipfile
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.io import limits
from pgc.io.mesh import read_mesh
from pgc.types import BodyMotion

MAX_FPS = 1000.0
"""Highest accepted frame rate (frames per second)."""
BODY_TOLERANCE = 0.2
"""Metres by which frame 0 of a motion may differ from the asset's capture body (bounding-box corners)."""


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
        limits.check_count(path, "frames", len(files), limits.MAX_MOTION_FRAMES, "OBJ frames")
        frames, faces = [], None
        for f in files:
            mesh = read_mesh(f)
            v = mesh.vertices
            if faces is None:
                faces = mesh.faces
            elif v.shape[0] != frames[0].shape[0]:
                raise PGCDataError(f"{f}: {v.shape[0]} vertices, but {files[0].name} has {frames[0].shape[0]}; "
                                   "every frame must share one topology")
            else:
                limits.check_count(path, "frames x vertices", len(files) * v.shape[0], limits.MAX_ELEMENTS,
                                   "positions")
            frames.append(v)
        stacked = np.stack(frames)
        if not np.all(np.isfinite(stacked)):
            raise PGCDataError(f"{path}: the OBJ frames hold non-finite vertex positions")
        return BodyMotion(stacked, faces, check_fps(float(fps or 30.0), f"{path}: fps"), name)
    if path.suffix.lower() != ".npz":
        raise PGCDataError(f"{path}: expected a folder of .obj frames or an .npz file")
    if not path.exists():
        raise PGCDataError(f"{path}: file not found")
    if not zipfile.is_zipfile(path):
        raise PGCDataError(f"{path}: not a readable .npz archive (not a zip file); save the motion with "
                           "numpy.savez(path, vertices=..., faces=..., fps=...)")
    try:
        _check_npz_shapes(path)
        with np.load(path, allow_pickle=False) as data:
            for key in ("vertices", "faces"):
                if key not in data:
                    raise PGCDataError(f"{path}: missing array '{key}' (need vertices (T, V, 3) and faces (F, 3))")
            vertices, faces = data["vertices"], data["faces"]
            raw_fps = data["fps"] if "fps" in data else np.float64(30.0)
    except PGCDataError:
        raise
    except ValueError as exc:
        if "pickle" not in str(exc):
            raise PGCDataError(f"{path}: not a readable .npz archive ({exc}); re-export it with numpy.savez") from None
        # object arrays (pickles) are refused by allow_pickle=False
        raise PGCDataError(f"{path}: holds object (pickled) arrays, which PGC does not load; save plain numeric "
                           f"arrays with numpy.savez ({exc})") from None
    except (OSError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise PGCDataError(f"{path}: not a readable .npz archive ({type(exc).__name__}: {exc}); re-export it "
                           "with numpy.savez") from None
    if not np.issubdtype(vertices.dtype, np.number) or vertices.ndim != 3 or vertices.shape[2] != 3 \
            or vertices.shape[0] == 0:
        raise PGCDataError(f"{path}: 'vertices' must be a numeric (T, V, 3) array with T >= 1, got "
                           f"{vertices.dtype} {vertices.shape}")
    if not np.issubdtype(faces.dtype, np.integer) or faces.ndim != 2 or faces.shape[1] != 3 or faces.size == 0:
        raise PGCDataError(f"{path}: 'faces' must be a non-empty integer (F, 3) array, got {faces.dtype} "
                           f"{faces.shape}")
    if faces.min() < 0 or faces.max() >= vertices.shape[1]:
        raise PGCDataError(f"{path}: 'faces' index out of range [0, {vertices.shape[1]})")
    bad = int(np.count_nonzero(~np.isfinite(vertices)))
    if bad:
        frame = int(np.argwhere(~np.isfinite(vertices))[0, 0])
        raise PGCDataError(f"{path}: 'vertices' holds {bad} non-finite values (first in frame {frame}); every "
                           "position must be a finite number of metres")
    if fps is None:
        if np.size(raw_fps) != 1 or not np.issubdtype(np.asarray(raw_fps).dtype, np.number):
            raise PGCDataError(f"{path}: 'fps' must be one number, got {np.asarray(raw_fps).dtype} "
                               f"{np.shape(raw_fps)}")
        fps = float(np.asarray(raw_fps).reshape(()))
    return BodyMotion(vertices.astype(np.float64), faces.astype(np.int64), check_fps(fps, f"{path}: 'fps'"), name)


def _check_npz_shapes(path: Path) -> None:
    """Refuse, from the arrays' headers (nothing loaded), a motion larger than :mod:`pgc.io.limits` allows."""
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            key = info.filename.removesuffix(".npy")
            if key not in ("vertices", "faces"):
                continue
            with zf.open(info) as f:
                version = np.lib.format.read_magic(f)
                read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) \
                    else np.lib.format.read_array_header_2_0
                shape = read_header(f)[0]
            if key == "vertices" and len(shape) == 3:
                limits.check_count(path, "'vertices' frames", shape[0], limits.MAX_MOTION_FRAMES, "frames")
            limits.check_count(path, f"'{key}' {shape}", math.prod(shape), 3 * limits.MAX_ELEMENTS, "values")


def check_fps(fps: float, where: str) -> float:
    """``fps`` if it is a finite positive frame rate (frames per second), else a clear error."""
    if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise PGCDataError(f"{where} must be a finite frame rate in (0, {MAX_FPS:g}] frames per second, got {fps}")
    return fps


def check_against_body(motion: BodyMotion, body_vertices: np.ndarray, where: str,
                       tolerance: float = BODY_TOLERANCE) -> None:
    """Refuse a motion whose frame 0 is not the capture pose of ``body_vertices`` (the asset's body, metres):
    the corners of the axis-aligned bounding boxes must agree within ``tolerance`` metres."""
    lo0, hi0 = motion.vertices[0].min(axis=0), motion.vertices[0].max(axis=0)
    body = np.asarray(body_vertices, np.float64)
    lo1, hi1 = body.min(axis=0), body.max(axis=0)
    gap = float(max(np.abs(lo0 - lo1).max(), np.abs(hi0 - hi1).max()))
    if gap > tolerance:
        shift = (lo0 + hi0) / 2 - (lo1 + hi1) / 2
        raise PGCDataError(f"{where}: frame 0 of the motion is not the asset's capture body (bounding boxes differ "
                           f"by {gap:.3f} m > {tolerance} m; centre offset {np.round(shift, 3).tolist()} m). "
                           "Frame 0 must be the capture pose, in the capture's coordinates and metres")
