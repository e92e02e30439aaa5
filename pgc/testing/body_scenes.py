"""A tiny body model file in SMPL's format (24 SMPL joints, a tetrahedron of vertices around each, 96 vertices),
made in-process: the ``smplx`` body model's tests and its bench workload run smplx's real loading and skinning
on it, since the licensed model files cannot ship."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np

SMPL_PARENTS = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21]
HALF = {0: (0, 0, 0), 1: (.08, -.08, 0), 3: (0, .1, 0), 4: (.09, -.45, 0), 6: (0, .25, 0), 7: (.09, -.85, 0),
        9: (0, .32, 0), 10: (.09, -.9, .1), 12: (0, .5, 0), 13: (.07, .42, 0), 15: (0, .62, 0),
        16: (.17, .45, 0), 18: (.42, .45, 0), 20: (.67, .45, 0), 22: (.75, .45, 0)}
"""Left-side and centre joints of a stick figure in SMPL's frame (metres); odd right-side ones mirror them."""


def tiny_smpl_arrays(seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    joints = np.zeros((24, 3))
    for j, p in HALF.items():
        joints[j] = p
        if j in (1, 4, 7, 10, 13, 16, 18, 20, 22):
            joints[j + 1] = (-p[0], p[1], p[2])
    tet = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) * 0.03 / np.sqrt(3)
    v_template = (joints[:, None] + tet[None]).reshape(-1, 3)
    faces = []
    for j in range(24):
        for tri in ([0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]):
            a, b, c = (4 * j + np.array(tri))
            n = np.cross(v_template[b] - v_template[a], v_template[c] - v_template[a])
            faces.append([a, b, c] if n @ (v_template[a] - joints[j]) > 0 else [a, c, b])
    V = len(v_template)
    weights = np.kron(np.eye(24), np.ones((4, 1)))
    shapedirs = rng.normal(0, 0.01, (V, 3, 10))
    shapedirs[:, 1, 0] = 0.05 * v_template[:, 1]  # beta0 stretches the body vertically
    # float32 arrays: smplx stores every model array at float32 precision (smplx.utils.to_np), whatever its dtype
    return {"v_template": v_template.astype(np.float32), "shapedirs": shapedirs.astype(np.float32),
            "posedirs": rng.normal(0, 1e-3, (V, 3, 207)).astype(np.float32),
            "J_regressor": (weights.T / 4.0).astype(np.float32), "weights": weights.astype(np.float32),
            "kintree_table": np.stack([np.array(SMPL_PARENTS) % 2**32, np.arange(24)]).astype(np.int64),
            "f": np.array(faces, dtype=np.int64)}


def write_tiny_smpl(path: str | Path, seed: int = 0) -> Path:
    """Write :func:`tiny_smpl_arrays` as an SMPL ``.pkl`` (pickle protocol 2, numpy arrays only) at ``path``."""
    path = Path(path)
    path.write_bytes(pickle.dumps(tiny_smpl_arrays(seed), protocol=2))
    return path
