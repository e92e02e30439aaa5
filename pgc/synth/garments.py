"""Garments built around the A-pose body as simulation-quality open shells with UVs.

A garment is the zero level of the body's own capsules grown by the looseness (torso, upper arms, thighs;
a flared frustum for a skirt), smooth-unioned, meshed, then cut exactly along the hem, the neckline and the
sleeve ends (:func:`pgc.synth.implicit.clip_mesh`), remeshed to roughly uniform triangles and unwrapped with
xatlas. Because every kept body part is grown by at least the looseness, the shell never intersects the
body in the A-pose. The 'resting' fit offsets the body's own surface instead, by :data:`RESTING_TOP_GAP` over
the shoulders and chest growing to the looseness at the waist, so the garment hangs from the shoulders.
"""

from __future__ import annotations

import functools

import numpy as np

from pgc.errors import PGCDataError
from pgc.synth import implicit
from pgc.synth.body import BLEND, BodyModel, body_parts
from pgc.synth.implicit import Cone
from pgc.synth.skeleton import JOINTS, BodyShape, joint_index, rest_joints
from pgc.types import Mesh

GARMENTS: tuple[str, ...] = ("tshirt", "dress")
FITS: tuple[str, ...] = ("loose", "resting")
RESTING_TOP_GAP = 0.005
"""Resting fit: clearance (metres) over the shoulders and the upper chest, where the garment hangs; the
simulation's cloth-body offset is 4 mm."""

_TORSO_JOINTS = ("pelvis", "spine1", "spine2", "spine3", "neck")


def _garment_field(shape: BodyShape, joints: np.ndarray, kind: str, looseness: float):
    h = shape.height
    parts = [c for c in body_parts(shape) if JOINTS[c.joint] in _TORSO_JOINTS + ("l_shoulder", "r_shoulder",
                                                                           "l_hip", "r_hip")]
    grow = {JOINTS[c.joint]: looseness for c in parts}
    grow.update({"l_shoulder": looseness * 1.3, "r_shoulder": looseness * 1.3})
    cones: list[Cone] = []
    if kind == "dress":
        waist = joints[joint_index("spine1")]
        cones.append(Cone((0.0, 0.0), y_top=float(waist[1]), y_bottom=0.24 * h, r_top=0.08 * h * shape.girth,
                          r_bottom=0.2 * h * shape.girth, depth=0.82))

    def field(p: np.ndarray) -> np.ndarray:
        fields = [implicit.capsule_field(p, c, grow[JOINTS[c.joint]]) for c in parts]
        fields += [implicit.cone_field(p, c, looseness) for c in cones]
        return implicit.smooth_union(fields, BLEND * h * 2.0)

    return field


def _resting_field(shape: BodyShape, joints: np.ndarray, kind: str, looseness: float):
    """Resting fit: the body's own smooth surface (without the legs) offset by a clearance that grows from
    :data:`RESTING_TOP_GAP` at the chest (0.72 h and up) to ``looseness`` at the waist (0.6 h and down), plus
    1 cm of ease under the arms and up to 8 mm more around the sleeves,
    united with a frustum from the waist down that the fabric hangs on over the hips (a skirt for the dress)."""
    h = shape.height
    legs = ("hip", "knee", "ankle", "foot")
    parts = [c for c in body_parts(shape) if not JOINTS[c.joint].endswith(legs)]  # it hangs over the hips
    waist = joints[joint_index("spine1")]
    r_bottom = (0.2 if kind == "dress" else 0.125) * h * shape.girth
    cones = [Cone((0.0, 0.0), y_top=float(waist[1]), y_bottom=0.24 * h, r_top=0.08 * h * shape.girth,
                  r_bottom=r_bottom, depth=0.82)]

    shoulder_x = float(joints[joint_index("l_shoulder")][0])
    armpits = [joints[joint_index(f"{side}_shoulder")] + np.array([sign * 0.018 * h, -0.07 * h, 0.0])
               for side, sign in (("l", 1.0), ("r", -1.0))]

    def field(p: np.ndarray) -> np.ndarray:
        t = np.clip((p[:, 1] - 0.6 * h) / (0.12 * h), 0.0, 1.0)
        gap = looseness + (RESTING_TOP_GAP - looseness) * t * t * (3 - 2 * t)
        for a in armpits:  # ease under the arms, where the sleeve meets the side
            gap = gap + 0.01 * np.exp(-np.sum((p - a) ** 2, axis=1) / (2 * (0.025 * h) ** 2))
        u = np.clip((np.abs(p[:, 0]) - shoulder_x) / (0.05 * h), 0.0, 1.0)  # the sleeves flare a little
        gap = gap + 0.008 * u * u * (3 - 2 * u)
        body = implicit.smooth_union([implicit.capsule_field(p, c) for c in parts], BLEND * h) - gap
        return implicit.smooth_union([body] + [implicit.cone_field(p, c, looseness) for c in cones], BLEND * h)

    return field


def _cut_field(shape: BodyShape, j: np.ndarray, kind: str, vertices: np.ndarray, sleeve: float, hem: float
               ) -> np.ndarray:
    """Per-vertex scalar, negative on the part of the closed surface that the garment keeps."""
    h = shape.height
    neck = j[joint_index("neck")]
    neck_r = (0.068 if kind == "tshirt" else 0.08) * h
    rho = np.hypot(vertices[:, 0] - neck[0], (vertices[:, 2] - neck[2] - 0.01 * h) / 0.85)
    cuts = [np.minimum(neck_r - rho, vertices[:, 1] - (neck[1] - 0.075 * h)),  # the neck opening
            hem - vertices[:, 1]]                                             # the hem
    for side in ("l", "r"):
        sh, el = j[joint_index(f"{side}_shoulder")], j[joint_index(f"{side}_elbow")]
        axis = (el - sh) / np.linalg.norm(el - sh)
        t = (vertices - sh) @ axis
        radial = np.linalg.norm((vertices - sh) - t[:, None] * axis, axis=1)
        cuts.append(np.minimum(t - sleeve, 0.09 * h - radial))                # the sleeve ends
    return np.max(np.stack(cuts), axis=0)


def make_garment(body: BodyModel, kind: str, looseness: float = 0.03, resolution: float = 0.02,
                 sleeve_length: float = 0.5, length: float = 1.0, fit: str = "loose") -> Mesh:
    """A garment shell around ``body`` in the A-pose.

    kind: 'tshirt' (loose, short sleeves) or 'dress' (cap sleeves, flared skirt to the knees);
    looseness: clearance from the body in metres (>= 0.01; loose fit: sleeves get 1.3x; resting fit: at the waist);
    resolution: target edge length in metres (0.02 gives about 2.6k vertices for the loose tshirt, 2.0k
    resting);
    sleeve_length: sleeve length as a fraction of the upper arm (tshirt; the dress uses a quarter of it);
    length: hem height scale (1 = hip for the tshirt, just above the knee for the dress; < 1 is longer);
    fit: 'loose' (the body's torso, upper-arm and thigh capsules grown by the looseness and blended wide:
    at 3 cm looseness the tshirt's vertices lie 2.4 cm off the body at least, 4.8 cm in the median) or
    'resting' (the body's own surface offset by :data:`RESTING_TOP_GAP` over the shoulders and chest,
    growing to ``looseness`` at the waist: the garment hangs from the shoulders).
    Returns a :class:`Mesh` with UVs (xatlas), face labels 2, name ``kind``.
    """
    if kind not in GARMENTS:
        raise PGCDataError(f"unknown garment '{kind}'; garments: {', '.join(GARMENTS)}")
    if not 0.01 <= looseness <= 0.15:
        raise PGCDataError(f"make_garment: looseness {looseness} m is outside [0.01, 0.15]")
    if not 0.006 <= resolution <= 0.08:
        raise PGCDataError(f"make_garment: resolution {resolution} m is outside [0.006, 0.08]")
    if not 0.1 <= sleeve_length <= 0.9 or not 0.7 <= length <= 1.2:
        raise PGCDataError("make_garment: sleeve_length must be in [0.1, 0.9] and length in [0.7, 1.2]")
    if fit not in FITS:
        raise PGCDataError(f"unknown garment fit '{fit}' (pgc synth --fit, or a preset's fit); use one of: "
                          f"{', '.join(FITS)}")
    v, f, uv, face_uv = _build(body.shape, kind, float(looseness), float(resolution), float(sleeve_length),
                               float(length), fit)
    return Mesh(v.copy(), f.copy(), uv.copy(), face_uv.copy(), np.full(len(f), 2, np.int32), name=kind)


@functools.lru_cache(maxsize=8)
def _build(shape: BodyShape, kind: str, looseness: float, resolution: float, sleeve_length: float,
           length: float, fit: str = "loose") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Garment arrays for a body shape (the garment depends on the body's parts, not its mesh)."""
    joints = rest_joints(shape)
    h = shape.height
    upper_arm = np.linalg.norm(joints[joint_index("l_elbow")] - joints[joint_index("l_shoulder")])
    sleeve = upper_arm * (sleeve_length if kind == "tshirt" else sleeve_length * 0.25)
    hem = (0.47 if kind == "tshirt" else 0.28) * h * length
    field = (_resting_field if fit == "resting" else _garment_field)(shape, joints, kind, looseness)
    lo = joints.min(axis=0) - 0.3 * h
    hi = joints.max(axis=0) + 0.15 * h
    spacing = float(np.clip(resolution / 2.5, 0.006, 0.016))  # marching-cubes grid
    lo[1] = max(lo[1], hem - 0.1 * h) + 0.37 * spacing  # keep grid planes off the hem plane
    hi[1] = 0.79 * h + 0.043 * h * shape.girth + looseness + 0.07  # above the shoulders, below the chin
    v, f = implicit.mesh_field(lambda p: np.maximum(field(p), np.maximum(lo[1] + 0.02 - p[:, 1],
                                                                          p[:, 1] - hi[1] + 0.02)),
                               lo, hi, spacing)
    v, f = implicit.clip_mesh(v, f, _cut_field(shape, joints, kind, v, sleeve, hem))
    v, f = implicit.remesh(v, f, resolution, merge=0.2 if fit == "resting" else 0.01)  # resting: no slivers
    uv, face_uv = unwrap(v, f)
    return v, f, uv, face_uv


def unwrap(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """UV atlas with xatlas: (T, 2) float32 uv in [0, 1] (v up) and (F, 3) face_uv indices."""
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_mesh(vertices.astype(np.float32), faces.astype(np.uint32))
    pack = xatlas.PackOptions()
    pack.padding = 4
    pack.resolution = 1024
    atlas.generate(pack_options=pack)
    _, indices, uvs = atlas[0]
    return uvs.astype(np.float32), indices.astype(np.int64)


def boundary_loops(mesh: Mesh) -> list[np.ndarray]:
    """Vertex index loops of the open boundaries of ``mesh`` (edges used by one face)."""
    e = np.concatenate([mesh.faces[:, [0, 1]], mesh.faces[:, [1, 2]], mesh.faces[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    nxt = {int(a): int(b) for a, b in e[counts[inv.ravel()] == 1]}
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop, cur = [], start
        while cur not in seen:
            seen.add(cur)
            loop.append(cur)
            cur = nxt[cur]
        loops.append(np.array(loop))
    return loops
