"""Mesh files: OBJ (with UV seams and labels), PLY (with a face label property), glTF/GLB.

- OBJ is read and written here (trimesh would split positions at UV seams): ``v``/``vt`` lists and
  ``f v/vt`` faces keep positions and texture vertices apart (:attr:`Mesh.face_uv`); per-face labels
  are OBJ groups ``g pgc_label_<id>``. Polygons are fan-triangulated; negative indices are supported.
- PLY and glTF/GLB go through trimesh. PLY keeps labels as the face property ``label`` (int); glTF
  cannot hold face data, so labels go to a sidecar ``<file>.labels.npy``. glTF splits vertices at UV
  seams; reading welds vertices with identical positions again. Both store float32 positions.

UVs are v-up in every file and in :class:`Mesh` (trimesh flips glTF's v-down on its own).
"""

from __future__ import annotations

import io
import os
import re
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.io import limits
from pgc.io.atomic import atomic_open, atomic_path
from pgc.types import Mesh

MESH_SUFFIXES = (".obj", ".ply", ".glb", ".gltf")
_LABEL_GROUP = re.compile(r"pgc_label_(\d+)$")


def _sidecar(path: Path) -> Path:
    return path.with_name(path.name + ".labels.npy")


def write_mesh(path: str | os.PathLike, mesh: Mesh) -> None:
    """Write ``mesh`` by suffix (.obj, .ply, .glb, .gltf), atomically."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise PGCDataError(f"{path}: unsupported mesh type '{suffix}'; use one of {', '.join(MESH_SUFFIXES)}")
    if suffix == ".obj":
        _write_obj(path, mesh)
        return
    import trimesh

    if suffix == ".ply":
        tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
        if mesh.face_labels is not None:
            tm.face_attributes["label"] = mesh.face_labels.astype(np.int32)
        data = trimesh.exchange.ply.export_ply(tm, encoding="binary", include_attributes=True)
        with atomic_open(path, "wb") as f:
            f.write(data)
        return
    vertices, faces, uv = mesh.vertices, mesh.faces, None
    if mesh.uv is not None:  # one glTF vertex per (position, uv) corner pair
        pairs = np.stack([mesh.faces.ravel(), mesh.face_uv.ravel()], axis=1)
        unique, inverse = np.unique(pairs, axis=0, return_inverse=True)
        vertices, uv, faces = mesh.vertices[unique[:, 0]], mesh.uv[unique[:, 1]], inverse.reshape(-1, 3)
    tm = trimesh.Trimesh(vertices, faces, process=False)
    if uv is not None:
        tm.visual = trimesh.visual.TextureVisuals(uv=uv)
    with atomic_path(path) as tmp:
        tm.export(tmp, file_type=suffix[1:])
    if mesh.face_labels is not None:
        with atomic_open(_sidecar(path), "wb") as f:
            np.save(f, mesh.face_labels)


def read_mesh(path: str | os.PathLike, name: str | None = None) -> Mesh:
    """Read a triangle mesh (.obj, .ply, .glb, .gltf); errors name the file and the problem."""
    path = Path(path)
    name = path.stem if name is None else name
    if not path.is_file():
        raise PGCDataError(f"{path}: file not found")
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise PGCDataError(f"{path}: unsupported mesh type '{suffix}'; use one of {', '.join(MESH_SUFFIXES)}")
    limits.check_file_size(path, limits.MAX_TEXT_BYTES, "mesh file")
    try:
        if suffix == ".obj":
            return _read_obj(path, name)
        return _read_trimesh(path, suffix, name)
    except PGCDataError as exc:
        msg = str(exc)
        raise PGCDataError(msg if msg.startswith(str(path)) else f"{path}: {msg}") from None


def _read_trimesh(path: Path, suffix: str, name: str) -> Mesh:
    import trimesh

    try:
        loaded = trimesh.load(path, file_type=suffix[1:], process=False, force=None)
    except Exception as exc:
        raise PGCDataError(f"{path}: cannot parse as {suffix[1:].upper()}: {type(exc).__name__}: {exc}") from None
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)] if loaded.geometry else []
        if not geoms:
            raise PGCDataError(f"{path}: the scene holds no triangle mesh")
        loaded = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise PGCDataError(f"{path}: not a triangle mesh (no faces; a point cloud?)")
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    labels = None
    if suffix == ".ply":
        raw = loaded.metadata.get("_ply_raw", {}).get("face", {}).get("data")
        if raw is not None and raw.dtype.names and "label" in raw.dtype.names:
            labels = np.asarray(raw["label"]).astype(np.int32)
        return Mesh(vertices, faces, face_labels=labels, name=name)
    uv = getattr(loaded.visual, "uv", None)
    if _sidecar(path).is_file():
        try:
            labels = np.load(_sidecar(path), allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise PGCDataError(f"{_sidecar(path)}: not a readable .npy array of face labels ({exc})") from None
        if labels.shape != (len(faces),):
            raise PGCDataError(f"{_sidecar(path)}: {labels.shape[0]} labels for {len(faces)} faces")
    # weld the vertices that the format split at UV seams
    welded, inverse = np.unique(vertices, axis=0, return_inverse=True)
    if uv is None:
        return Mesh(welded, inverse.reshape(-1)[faces], face_labels=labels, name=name)
    return Mesh(welded, inverse.reshape(-1)[faces], uv=np.asarray(uv, np.float32), face_uv=faces,
                face_labels=labels, name=name)


def _write_obj(path: Path, mesh: Mesh) -> None:
    buf = io.StringIO()
    buf.write(f"# PGC mesh '{mesh.name}': {len(mesh.vertices)} vertices, {len(mesh.faces)} faces\n")
    np.savetxt(buf, mesh.vertices, fmt="v %.17g %.17g %.17g")
    if mesh.uv is not None:
        np.savetxt(buf, mesh.uv.astype(np.float64), fmt="vt %.9g %.9g")
    f1 = mesh.faces + 1
    if mesh.uv is not None:
        t1 = mesh.face_uv + 1
        rows = np.stack([f1[:, 0], t1[:, 0], f1[:, 1], t1[:, 1], f1[:, 2], t1[:, 2]], axis=1)
        fmt = "f %d/%d %d/%d %d/%d"
    else:
        rows, fmt = f1, "f %d %d %d"
    if mesh.face_labels is None:
        np.savetxt(buf, rows, fmt=fmt)
    else:  # faces grouped by label, in file order within a group; the face order is kept via 'pgc_order'
        order = np.argsort(mesh.face_labels, kind="stable")
        if not np.array_equal(order, np.arange(len(order))):
            buf.write("# pgc_order " + " ".join(map(str, order)) + "\n")
        labels = mesh.face_labels[order]
        starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
        for s, e in zip(starts, np.r_[starts[1:], len(order)]):
            buf.write(f"g pgc_label_{labels[s]}\n")
            np.savetxt(buf, rows[order[s:e]], fmt=fmt)
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(buf.getvalue())


def _obj_index(token: str, count: int, path: Path, lineno: int, kind: str) -> int:
    i = int(token)
    i = i - 1 if i > 0 else count + i
    if not 0 <= i < count:
        raise PGCDataError(f"{path}:{lineno}: {kind} index {token} out of range (1..{count})")
    return i


def _read_obj(path: Path, name: str) -> Mesh:
    vertices: list[list[float]] = []
    uvs: list[list[float]] = []
    faces: list[list[int]] = []
    face_uv: list[list[int]] = []
    labels: list[int] = []
    label, has_labels, order = 0, False, None
    with open(path, encoding="utf-8", errors="replace") as f:
        for lineno, line in enumerate(f, 1):
            parts = line.split()
            if not parts:
                continue
            key = parts[0]
            try:
                if key == "v":
                    vertices.append([float(x) for x in parts[1:4]])
                elif key == "vt":
                    uvs.append([float(x) for x in parts[1:3]])
                elif key in ("g", "o", "usemtl") and len(parts) > 1 and _LABEL_GROUP.match(parts[1]):
                    label, has_labels = int(_LABEL_GROUP.match(parts[1]).group(1)), True
                elif key == "#" and len(parts) > 1 and parts[1] == "pgc_order":
                    order = np.array([int(x) for x in parts[2:]], dtype=np.int64)
                elif key == "f":
                    corners = [c.split("/") for c in parts[1:]]
                    if len(corners) < 3:
                        raise PGCDataError(f"{path}:{lineno}: a face needs at least 3 vertices")
                    vi = [_obj_index(c[0], len(vertices), path, lineno, "vertex") for c in corners]
                    ti = ([_obj_index(c[1], len(uvs), path, lineno, "texture")
                           for c in corners] if all(len(c) > 1 and c[1] for c in corners) else None)
                    for k in range(1, len(vi) - 1):
                        faces.append([vi[0], vi[k], vi[k + 1]])
                        if ti is not None:
                            face_uv.append([ti[0], ti[k], ti[k + 1]])
                        labels.append(label)
            except ValueError as exc:
                raise PGCDataError(f"{path}:{lineno}: cannot parse '{line.strip()[:60]}' ({exc})") from None
    if not faces:
        raise PGCDataError(f"{path}: no faces; not a triangle mesh")
    if face_uv and len(face_uv) != len(faces):
        raise PGCDataError(f"{path}: {len(face_uv)} of {len(faces)} faces have texture coordinates; "
                           "give them for all faces or none")
    if any(len(v) != 3 for v in vertices):
        raise PGCDataError(f"{path}: a 'v' line has fewer than 3 coordinates")
    F, T, L = np.array(faces), np.array(face_uv) if face_uv else None, np.array(labels)
    if order is not None:
        if sorted(order.tolist()) != list(range(len(F))):
            raise PGCDataError(f"{path}: 'pgc_order' comment is not a permutation of the {len(F)} faces")
        inv = np.empty_like(order)
        inv[order] = np.arange(len(order))
        F, L = F[inv], L[inv]
        T = None if T is None else T[inv]
    uv = np.array(uvs, dtype=np.float32).reshape(-1, 2) if T is not None else None
    return Mesh(np.array(vertices), F, uv=uv, face_uv=T, face_labels=L if has_labels else None, name=name)
