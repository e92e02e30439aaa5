"""Gaussian splats as the standard 3DGS ``.ply``, plus the mesh binding of PGC as extra properties.

Standard layout (binary little endian, one ``vertex`` element, float32 properties in this order)::

    x y z nx ny nz f_dc_0 f_dc_1 f_dc_2 f_rest_0 .. f_rest_44 opacity scale_0 scale_1 scale_2 rot_0 .. rot_3

``opacity`` is the logit of opacity, ``scale_*`` the natural log of the standard deviations, ``rot_*`` the
quaternion (w, x, y, z), ``f_rest`` grouped by colour channel (all R coefficients 1..15, then G, then B;
index ``c * 15 + (k - 1)``). Normals are written as zeros. ``f_rest`` is always padded to degree 3
(45 values, what common viewers expect); a ``comment pgc_sh_degree D`` header line records the true degree.

A *bound* file (an asset's ``gaussians.ply``) holds the world parameters baked on the rest mesh, so it opens
in ordinary splat viewers, followed by the binding: ``pgc_parent`` (int, parent face), ``pgc_mu_0..2``
(local position), ``pgc_rot_0..3`` (local quaternion, wxyz), ``pgc_log_scale_0..2`` (local log scale);
opacity logit and SH are shared with the standard columns. Reading a bound file returns the exact
:class:`GaussianSet` that was written.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.io import limits
from pgc.io.atomic import atomic_open
from pgc.types import GaussianSet, WorldGaussians

SH_REST = 15
"""SH coefficients beyond DC per channel at degree 3."""
LOG_SCALE_FLOOR = -80.0
"""log(scale) written for zero scales (exp(-80) ~ 1.8e-35, a float32 normal number)."""

STANDARD_PROPERTIES = (["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
                       + [f"f_rest_{i}" for i in range(3 * SH_REST)]
                       + ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"])
BINDING_PROPERTIES = (["pgc_parent"] + [f"pgc_mu_{i}" for i in range(3)] + [f"pgc_rot_{i}" for i in range(4)]
                      + [f"pgc_log_scale_{i}" for i in range(3)])
REQUIRED = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
            "rot_0", "rot_1", "rot_2", "rot_3"]

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def _header_int(path: Path, text: str, line: str) -> int:
    """A non-negative integer of a PLY header line, else a clear error."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise PGCDataError(f"{path}: header line '{line}': '{text}' is not a non-negative integer count")
    return value


def _logit(p: np.ndarray) -> np.ndarray:
    p = np.clip(np.asarray(p, dtype=np.float64), 1e-7, 1.0 - 1e-7)
    return np.log(p) - np.log1p(-p)


Block = tuple[list[str], np.ndarray]
"""Consecutive properties and their (N, k) values."""


def _sh_rest(sh: np.ndarray) -> np.ndarray:
    """(N, K, 3) SH -> (N, 45) f_rest grouped by channel, zero padded to degree 3."""
    n, k, _ = sh.shape
    rest = np.zeros((n, 3, SH_REST), dtype=np.float32)
    rest[:, :, : k - 1] = np.transpose(sh[:, 1:, :], (0, 2, 1))
    return rest.reshape(n, 3 * SH_REST)


def _write(path: str | os.PathLike, blocks: list[Block], sh_degree: int) -> None:
    """Write the blocks as one binary little-endian ``vertex`` element (float32; int32 for ``pgc_parent``)."""
    n = len(blocks[0][1])
    names = [name for block_names, _ in blocks for name in block_names]
    data = np.empty((n, len(names)), dtype="<f4")
    col = 0
    for block_names, values in blocks:
        values = np.asarray(values).reshape(n, len(block_names))
        if np.issubdtype(values.dtype, np.integer):  # int32 bits stored in a float32 slot
            data[:, col:col + len(block_names)] = values.astype("<i4").view("<f4")
        else:
            data[:, col:col + len(block_names)] = values
        col += len(block_names)
    header = ["ply", "format binary_little_endian 1.0", f"comment pgc_sh_degree {sh_degree}", f"element vertex {n}"]
    header += [f"property {'int' if name == 'pgc_parent' else 'float'} {name}" for name in names]
    header.append("end_header\n")
    with atomic_open(path, "wb") as f:
        f.write("\n".join(header).encode("ascii"))
        f.write(data)  # C-contiguous: written through the buffer protocol, no copy


def _standard_blocks(means, quats, log_scales, opacity_logits, sh) -> list[Block]:
    sh = np.asarray(sh, dtype=np.float32)
    n = len(sh)
    p = STANDARD_PROPERTIES
    return [(p[0:3], means), (p[3:6], np.zeros((n, 3), np.float32)), (p[6:9], sh[:, 0, :]), (p[9:54], _sh_rest(sh)),
            (p[54:55], opacity_logits), (p[55:58], log_scales), (p[58:62], quats)]


def _check_world(g: WorldGaussians) -> None:
    n = len(g.means)
    shapes = {"means": (n, 3), "quats": (n, 4), "scales": (n, 3), "opacities": (n,)}
    for name, shape in shapes.items():
        if np.shape(getattr(g, name)) != shape:
            raise PGCDataError(f"gaussians: '{name}' must have shape {shape}, got {np.shape(getattr(g, name))}")
    sh = np.asarray(g.sh)
    if sh.ndim != 3 or sh.shape[0] != n or sh.shape[2] != 3 or sh.shape[1] not in (1, 4, 9, 16):
        raise PGCDataError(f"gaussians: 'sh' must have shape (N, (D+1)^2, 3) with D <= 3, got {sh.shape}")


def write_world_gaussians_ply(path: str | os.PathLike, gaussians: WorldGaussians) -> None:
    """Write world-space Gaussians as a standard 3DGS ``.ply`` (float32; see the module docstring)."""
    _check_world(gaussians)
    scales = np.asarray(gaussians.scales, dtype=np.float64)
    with np.errstate(divide="ignore"):
        log_scales = np.maximum(np.log(np.maximum(scales, 0.0)), LOG_SCALE_FLOOR)
    sh = np.asarray(gaussians.sh)
    blocks = _standard_blocks(gaussians.means, gaussians.quats, log_scales, _logit(gaussians.opacities), sh)
    _write(path, blocks, int(round(np.sqrt(sh.shape[1]))) - 1)


def write_bound_gaussians_ply(path: str | os.PathLike, gaussians: GaussianSet, vertices: np.ndarray,
                              faces: np.ndarray) -> None:
    """Write mesh-embedded Gaussians: world parameters baked on the mesh (vertices (V, 3), faces (F, 3)),
    then the binding columns; :func:`read_bound_gaussians_ply` returns ``gaussians`` exactly."""
    from pgc.splats.binding import bind

    world = bind(gaussians, vertices, faces)
    with np.errstate(divide="ignore"):
        world_log_scales = np.maximum(np.log(world.scales), LOG_SCALE_FLOOR)
    blocks = _standard_blocks(world.means, world.quats, world_log_scales, gaussians.opacity_logits, gaussians.sh)
    b = BINDING_PROPERTIES
    blocks += [(b[0:1], gaussians.parent), (b[1:4], gaussians.means), (b[4:8], gaussians.quats),
               (b[8:11], gaussians.log_scales)]
    _write(path, blocks, gaussians.sh_degree)


def _parse(path: Path) -> tuple[np.ndarray, int | None]:
    """The ``vertex`` element of a PLY file as a structured array, and the recorded SH degree if any."""
    if not path.is_file():
        raise PGCDataError(f"{path}: file not found")
    limits.check_file_size(path, limits.MAX_TEXT_BYTES, "PLY file")
    raw = path.read_bytes()
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise PGCDataError(f"{path}: not a PLY file (no 'ply' magic or no 'end_header')")
    body = end + len(b"end_header")
    body += 2 if raw[body:body + 2] == b"\r\n" else 1
    lines = raw[:end].decode("ascii", errors="replace").splitlines()
    fmt, degree = None, None
    elements: list[tuple[str, int, list[tuple[str, str]]]] = []
    for line in lines[1:]:
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "format":
            fmt = parts[1]
        elif parts[0] == "comment" and len(parts) == 3 and parts[1] == "pgc_sh_degree":
            degree = _header_int(path, parts[2], line)
        elif parts[0] == "element":
            if len(parts) != 3:
                raise PGCDataError(f"{path}: header line '{line}' must be 'element NAME COUNT'")
            count = limits.check_count(path, f"header line '{line}'", _header_int(path, parts[2], line),
                                       limits.MAX_ELEMENTS)
            elements.append((parts[1], count, []))
        elif parts[0] == "property":
            if not elements:
                raise PGCDataError(f"{path}: property before any element in the header")
            if parts[1] == "list":
                elements[-1][2].append((parts[-1], "list"))
            elif parts[1] not in _PLY_TYPES:
                raise PGCDataError(f"{path}: unknown PLY property type '{parts[1]}'")
            else:
                elements[-1][2].append((parts[2], _PLY_TYPES[parts[1]]))
    if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
        raise PGCDataError(f"{path}: unsupported PLY format '{fmt}'")
    offset = body
    for name, count, props in elements:
        if any(t == "list" for _, t in props):
            raise PGCDataError(f"{path}: element '{name}' has list properties; a Gaussian .ply holds only a "
                               "'vertex' element of scalar properties")
        order = "<" if fmt == "binary_little_endian" else ">"
        names = [p for p, _ in props]
        if len(set(names)) != len(names):
            raise PGCDataError(f"{path}: element '{name}' repeats a property name ({names})")
        dtype = np.dtype([(p, order + t) for p, t in props])
        if name == "vertex":
            if fmt == "ascii":
                text = raw[offset:].decode("ascii", errors="replace").split("\n")[:count]
                try:
                    values = np.array([row.split() for row in text], dtype=np.float64).reshape(count, len(props))
                except ValueError:
                    raise PGCDataError(f"{path}: the ASCII body does not hold {count} rows of {len(props)} numbers "
                                       "as the header says") from None
                data = np.empty(count, dtype=dtype.newbyteorder("="))
                for i, (p, _) in enumerate(props):
                    data[p] = values[:, i]
                return data, degree
            if len(raw) < offset + count * dtype.itemsize:
                raise PGCDataError(f"{path}: truncated: {count} vertices need {count * dtype.itemsize} bytes, "
                                   f"the file has {len(raw) - offset}")
            return np.frombuffer(raw, dtype=dtype, count=count, offset=offset), degree
        if fmt == "ascii":
            raise PGCDataError(f"{path}: an ASCII PLY must have 'vertex' as its first element")
        offset += count * dtype.itemsize
    raise PGCDataError(f"{path}: no 'vertex' element")


def _columns(path: Path, data: np.ndarray, names: list[str]) -> np.ndarray:
    missing = [n for n in names if n not in data.dtype.names]
    if missing:
        raise PGCDataError(f"{path}: missing PLY propert{'y' if len(missing) == 1 else 'ies'} "
                           f"{', '.join(repr(m) for m in missing)} in element 'vertex'")
    out = np.stack([data[n].astype(np.float64) for n in names], axis=1) if names else np.zeros((len(data), 0))
    if not np.all(np.isfinite(out)):
        bad = [n for n in names if not np.all(np.isfinite(data[n]))]
        raise PGCDataError(f"{path}: properties {bad} hold NaN or Inf")
    return out


def _read_sh(path: Path, data: np.ndarray, degree: int | None) -> np.ndarray:
    n_rest = sum(1 for n in data.dtype.names if re.fullmatch(r"f_rest_\d+", n))
    if n_rest % 3 or round(np.sqrt(n_rest // 3 + 1)) ** 2 != n_rest // 3 + 1 or n_rest > 45:
        raise PGCDataError(f"{path}: {n_rest} f_rest properties is not 3 * ((D+1)^2 - 1) for a degree D <= 3")
    per_channel = n_rest // 3
    dc = _columns(path, data, ["f_dc_0", "f_dc_1", "f_dc_2"])
    rest = _columns(path, data, [f"f_rest_{i}" for i in range(n_rest)]).reshape(len(data), 3, per_channel)
    sh = np.concatenate([dc[:, None, :], np.transpose(rest, (0, 2, 1))], axis=1)
    if degree is not None:
        if not 0 <= degree <= 3 or (degree + 1) ** 2 > sh.shape[1]:
            raise PGCDataError(f"{path}: header says pgc_sh_degree {degree} but has {n_rest} f_rest properties")
        sh = sh[:, : (degree + 1) ** 2]
    return sh


def read_world_gaussians_ply(path: str | os.PathLike) -> WorldGaussians:
    """Read a standard 3DGS ``.ply`` (any SH degree 0-3) as activated world-space Gaussians (float64)."""
    path = Path(path)
    data, degree = _parse(path)
    cols = _columns(path, data, REQUIRED)
    opacity_logit = cols[:, 6]
    return WorldGaussians(means=cols[:, 0:3], quats=cols[:, 10:14], scales=np.exp(cols[:, 7:10]),
                          opacities=0.5 * (1.0 + np.tanh(0.5 * opacity_logit)), sh=_read_sh(path, data, degree))


def read_bound_gaussians_ply(path: str | os.PathLike) -> GaussianSet:
    """Read the mesh binding of a file written by :func:`write_bound_gaussians_ply` (exact round trip)."""
    path = Path(path)
    data, degree = _parse(path)
    if "pgc_parent" not in data.dtype.names:
        raise PGCDataError(f"{path}: missing PLY property 'pgc_parent': this is a plain 3DGS file without a "
                           "mesh binding; read it with read_world_gaussians_ply")
    binding = _columns(path, data, BINDING_PROPERTIES)
    parent = data["pgc_parent"].astype(np.int64)
    opacity = _columns(path, data, ["opacity"])[:, 0]
    return GaussianSet(parent=parent, means=binding[:, 1:4], quats=binding[:, 4:8], log_scales=binding[:, 8:11],
                       opacity_logits=opacity, sh=_read_sh(path, data, degree))
