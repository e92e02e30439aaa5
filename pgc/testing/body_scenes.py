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


FIT_GARMENTS = {"tight": 0.008, "loose": 0.035}
"""Fixture garments of :func:`anny_capture`: clearance from the body, metres."""
TORSO_JOINTS = ("Hips", "LowerBack", "Spine", "Spine1", "LeftShoulder", "RightShoulder", "LHipJoint", "RHipJoint")
"""Joints whose skin the fixture's shirt covers."""


def fixture_pose(body, angles_deg: dict[str, tuple[float, float, float]]) -> np.ndarray:
    """(J, 3, 3) rotations of ``body``: identity except the named joints' XYZ Euler angles (degrees)."""
    from scipy.spatial.transform import Rotation

    rotations = np.broadcast_to(np.eye(3), (len(body.joint_names), 3, 3)).copy()
    for name, xyz in angles_deg.items():
        rotations[body.joint_names.index(name)] = Rotation.from_euler("xyz", xyz, degrees=True).as_matrix()
    return rotations


def fixture_garment(body, state, clearance: float):
    """A shirt: the body faces skinned mostly to :data:`TORSO_JOINTS`, pushed ``clearance`` metres out along the
    vertex normals (an open shell, label garment), as a :class:`pgc.types.Mesh` with a one-texel UV."""
    from pgc.types import GARMENT_LABEL, Mesh

    torso = np.isin(np.asarray(body.joint_names)[np.argmax(body.weights, axis=1)], TORSO_JOINTS)
    faces = state.faces[torso[state.faces].all(axis=1)]
    v = state.vertices
    n = np.zeros_like(v)
    fn = np.cross(v[state.faces[:, 1]] - v[state.faces[:, 0]], v[state.faces[:, 2]] - v[state.faces[:, 0]])
    for k in range(3):
        np.add.at(n, state.faces[:, k], fn)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    used, faces = np.unique(faces, return_inverse=True)
    faces = faces.reshape(-1, 3)
    return Mesh(v[used] + clearance * n[used], faces, np.zeros((1, 2), np.float32), np.zeros_like(faces),
                np.full(len(faces), GARMENT_LABEL, np.int32), name="garment")


def anny_capture(body, renderer, shape: dict, rotations: np.ndarray, translation=(0.0, 0.0, 0.0),
                 garment: str | None = "tight", views: int = 8, size: int = 64):
    """A capture of ``body`` (a body_model) in a known shape and pose, wearing a :func:`fixture_garment`, seen by
    dome cameras: masks and segmentation from ``renderer``'s exact ground-truth layers (a flat grey image; the
    body fit reads only masks and labels). Returns (capture, posed state, garment mesh or None)."""
    from pgc.roles.scene_renderer import SceneGeometry
    from pgc.testing.capture_scenes import dome_cameras
    from pgc.types import Capture, Light, Material, Mesh, View

    state = body.forward(shape, rotations, np.asarray(translation, float))
    cloth = None if garment is None else fixture_garment(body, state, FIT_GARMENTS[garment])
    empty = Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), name="garment")
    material = Material("lambertian", {"base_color": [0.5, 0.5, 0.5]}, None)
    geometry = SceneGeometry(state.vertices, state.faces, cloth if cloth is not None else empty, material)
    scene, labels = renderer.build_scene(geometry, Light(np.ones(3)))
    height = float(np.ptp(state.vertices[:, 1]))
    out = []
    for cam in dome_cameras(views, size, radius=3.2, target_y=0.5 * height + float(translation[1]),
                            fov_y_deg=40.0):
        layers = renderer.ground_truth_layers(scene, labels, geometry, cam, 4)
        out.append(View(cam, np.full((size, size, 3), 0.5, np.float32), layers["mask"], layers["segmentation"]))
    return Capture(out), state, cloth


def random_body(body, seed: int) -> tuple[dict[str, float], np.ndarray]:
    """An adult's shape (Anny's phenotypes; age between young and middle-aged) and a capture pose near the rest
    A-pose (arms, elbows, legs, neck and spine turned by up to 15 degrees), drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    shape = {"gender": rng.uniform(0.0, 1.0), "age": rng.uniform(0.55, 0.85), "muscle": rng.uniform(0.2, 0.8),
             "weight": rng.uniform(0.2, 0.8), "height": rng.uniform(0.2, 0.8), "proportions": rng.uniform(0.2, 0.8)}
    joints = ("LeftArm", "RightArm", "LeftForeArm", "RightForeArm", "LeftUpLeg", "RightUpLeg", "Neck", "Spine")
    angles = {j: tuple(rng.uniform(-15.0, 15.0, 3) * (0.4 if j in ("Neck", "Spine") else 1.0)) for j in joints}
    return {k: float(v) for k, v in shape.items()}, fixture_pose(body, angles)
