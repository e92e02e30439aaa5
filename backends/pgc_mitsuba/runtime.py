"""Importing Mitsuba for PGC: the LLVM (CPU) differentiable RGB variant, with a working libLLVM found.

Dr.Jit's LLVM backend crashes with Debian's libLLVM-15 ("Cannot select fminimum"); LLVM 19 works. Unless
the user set ``DRJIT_LIBLLVM_PATH``, we point it at the newest libLLVM >= 19 found on the system before
Dr.Jit loads. Use :func:`mitsuba` instead of ``import mitsuba``.
"""

from __future__ import annotations

import glob
import os
import re
from typing import Any

import numpy as np

DEFAULT_VARIANT = "llvm_ad_rgb"
_SEARCH = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib/llvm-*/lib", "/usr/lib",
           "/usr/local/lib", "/opt/homebrew/opt/llvm/lib")


def find_libllvm(min_major: int = 19) -> str | None:
    """Path of the newest libLLVM shared library with major version >= ``min_major``, or None."""
    best: tuple[int, str] | None = None
    for folder in _SEARCH:
        for path in glob.glob(os.path.join(folder, "libLLVM*.so*")):
            m = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
            if m and int(m.group(1)) >= min_major and (best is None or int(m.group(1)) > best[0]):
                best = (int(m.group(1)), path)
    return None if best is None else best[1]


def mitsuba(variant: str = DEFAULT_VARIANT) -> Any:
    """Import Mitsuba with ``variant`` set (LLVM library located first) and return the module."""
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        lib = find_libllvm()
        if lib is not None:
            os.environ["DRJIT_LIBLLVM_PATH"] = lib
    import mitsuba as mi

    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi


def mesh_to_mitsuba(vertices: np.ndarray, faces: np.ndarray, name: str = "mesh", uv: np.ndarray | None = None,
                    face_uv: np.ndarray | None = None, bsdf: Any = None, vertex_normals: bool = False) -> Any:
    """Build an ``mi.Mesh`` from arrays. Positions are split per face-corner where UV seams require it.

    ``uv`` with ``face_uv``: per-corner texture coordinates (v up, as in :class:`pgc.types.Mesh`), passed
    unchanged. Mitsuba's bitmap texture reads row ``v H`` (v = 0 is the top row), so a texture in PGC's
    v-up convention must be flipped vertically when given to Mitsuba (``pgc_mitsuba.bsdfs`` does it).
    ``vertex_normals``: smooth shading with area-weighted normals of the unsplit mesh, so UV seams do not
    show as shading creases.
    """
    mi = mitsuba()
    vertices = np.asarray(vertices, dtype=np.float32)
    faces = np.asarray(faces, dtype=np.int64)
    if uv is not None and face_uv is not None:
        # One Mitsuba vertex per distinct (position, uv) corner pair, in lexicographic order of the pair: the
        # pair as one integer key (position x uv count + uv) sorts the same way, and a 1D unique is ~10x faster
        # than np.unique(axis=0) (1.0 s -> 0.1 s on the 1.4M corners of a detailed ground-truth garment).
        uv = np.asarray(uv, np.float32)
        n_uv = max(len(uv), 1)
        keys = faces.reshape(-1) * n_uv + np.asarray(face_uv, np.int64).reshape(-1)
        pairs, inverse = np.unique(keys, return_inverse=True)
        source = pairs // n_uv
        positions, texcoords = vertices[source], uv[pairs % n_uv]
        tri = inverse.reshape(-1, 3)
    else:
        source = np.arange(len(vertices))
        positions, texcoords, tri = vertices, None, faces
    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = bsdf
    m = mi.Mesh(name, vertex_count=len(positions), face_count=len(tri), has_vertex_normals=vertex_normals,
                has_vertex_texcoords=texcoords is not None, props=props)
    params = mi.traverse(m)
    params["vertex_positions"] = mi.Float(positions.reshape(-1))
    params["faces"] = mi.UInt32(tri.astype(np.uint32).reshape(-1))
    if texcoords is not None:
        params["vertex_texcoords"] = mi.Float(texcoords.reshape(-1))
    if vertex_normals:
        from pgc.types import Mesh

        normals = Mesh(vertices, faces).vertex_normals()[source].astype(np.float32)
        params["vertex_normals"] = mi.Float(normals.reshape(-1))
    params.update()
    return m
