"""Garments fitted to the synthetic body in the capture pose, as simulation-quality open shells with UVs.

A garment is the zero level of the body's own signed distance field (:meth:`pgc.synth.body.SynthBody.field`)
offset by the clearance, smooth-unioned with an elliptic frustum over the hips that the fabric hangs on (sized
to enclose this body's hips and thighs; flared into a skirt for the dress), meshed, then cut exactly along the
hem, the neckline and the sleeve ends (:func:`pgc.synth.implicit.clip_mesh`), remeshed to roughly uniform
triangles and unwrapped with xatlas. Fit 'loose' offsets the body by the looseness everywhere (1.3 times on the
sleeves); fit 'resting' by :data:`RESTING_TOP_GAP` over the shoulders and chest, growing to the looseness at
the waist, so the garment hangs from the shoulders.
"""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError
from pgc.synth import implicit
from pgc.synth.body import SynthBody
from pgc.synth.implicit import Cone
from pgc.types import Mesh

GARMENTS: tuple[str, ...] = ("tshirt", "dress")
FITS: tuple[str, ...] = ("loose", "resting")
RESTING_TOP_GAP = 0.005
"""Resting fit: clearance (metres) over the shoulders and the upper chest, where the garment hangs; the
simulation's cloth-body offset is 4 mm."""
BLEND = 0.012
"""Smooth-union blend radius of the body and the hip frustum, as a fraction of the height."""
SAG_RADIUS = 0.05
"""Resting fit: the clearance grows by the sag of a straight edge of the garment's resolution over a surface of
this radius of curvature (metres, an upper arm's), so no edge cuts through the body: resolution^2 / (8 r)."""
ARM_WORDS = ("Arm", "Hand", "Finger", "Thumb")
"""Rig joints whose vertices are the arms (left out when sizing the hip frustum)."""


def hip_cone(body: SynthBody, kind: str, hem: float) -> Cone:
    """The frustum from the waist down that the garment hangs on: it encloses the body's vertices (arms left
    out) between the hem and the waist; the dress's flares to at least 0.2 of the height at its bottom."""
    h = body.height
    y_top, y_bottom = float(body.joint("waist")[1]), 0.24 * h
    dominant = np.asarray(body.joint_names)[np.argmax(body.weights, axis=1)]
    trunk = ~np.array([any(w in name for w in ARM_WORDS) for name in dominant])
    v = body.vertices[trunk & (body.vertices[:, 1] >= hem - 0.02) & (body.vertices[:, 1] <= y_top + 0.02)]
    cz = 0.5 * (v[:, 2].min() + v[:, 2].max())
    depth = float(np.clip((v[:, 2].max() - v[:, 2].min()) / max(2 * np.abs(v[:, 0]).max(), 1e-6), 0.6, 1.0))
    rho = np.hypot(v[:, 0], (v[:, 2] - cz) / depth)
    t = np.clip((y_top - v[:, 1]) / (y_top - y_bottom), 0.0, 1.0)
    r_top = float(rho[t < 0.05].max(initial=0.08 * h))
    deep = t >= 0.05
    r_bottom = max(float(np.max(r_top + (rho[deep] - r_top) / t[deep], initial=r_top)),
                   0.2 * h if kind == "dress" else 0.0)
    return Cone((0.0, cz), y_top=y_top, y_bottom=y_bottom, r_top=r_top, r_bottom=r_bottom, depth=depth)


def _garment_field(body: SynthBody, cone: Cone, looseness: float):
    """Loose fit: the body grown by the looseness (1.3 times beyond the shoulders), united with the frustum."""
    h, shoulder_x = body.height, float(body.joint("l_shoulder")[0])
    exact = 1.3 * looseness + 0.07

    def field(p: np.ndarray) -> np.ndarray:
        u = np.clip((np.abs(p[:, 0]) - shoulder_x) / (0.05 * h), 0.0, 1.0)
        grow = looseness * (1 + 0.3 * u * u * (3 - 2 * u))
        return implicit.smooth_union([body.field(p, exact) - grow, implicit.cone_field(p, cone, looseness)],
                                     2 * BLEND * h)

    return field


def _resting_field(body: SynthBody, cone: Cone, looseness: float, resolution: float):
    """Resting fit: the body's surface offset by a clearance that grows from :data:`RESTING_TOP_GAP` at the
    chest (0.72 h and up) to ``looseness`` at the waist (0.6 h and down), plus 1 cm of ease under the arms, up
    to 8 mm more around the sleeves and the sag of an edge of ``resolution`` (:data:`SAG_RADIUS`), united with
    the frustum over the hips."""
    h, shoulder_x = body.height, float(body.joint("l_shoulder")[0])
    armpits = [body.joint(f"{side}_shoulder") + np.array([sign * 0.018 * h, -0.07 * h, 0.0])
               for side, sign in (("l", 1.0), ("r", -1.0))]
    exact = looseness + 0.07
    sag = resolution ** 2 / (8 * SAG_RADIUS)

    def field(p: np.ndarray) -> np.ndarray:
        t = np.clip((p[:, 1] - 0.6 * h) / (0.12 * h), 0.0, 1.0)
        gap = looseness + (RESTING_TOP_GAP - looseness) * t * t * (3 - 2 * t) + sag
        for a in armpits:  # ease under the arms, where the sleeve meets the side
            gap = gap + 0.01 * np.exp(-np.sum((p - a) ** 2, axis=1) / (2 * (0.025 * h) ** 2))
        u = np.clip((np.abs(p[:, 0]) - shoulder_x) / (0.05 * h), 0.0, 1.0)  # the sleeves flare a little
        gap = gap + 0.008 * u * u * (3 - 2 * u)
        return implicit.smooth_union([body.field(p, exact) - gap, implicit.cone_field(p, cone, looseness)], BLEND * h)

    return field


def _cut_field(body: SynthBody, kind: str, vertices: np.ndarray, sleeve: float, hem: float) -> np.ndarray:
    """Per-vertex scalar, negative on the part of the closed surface that the garment keeps."""
    h = body.height
    neck = body.joint("neck")
    neck_r = (0.068 if kind == "tshirt" else 0.08) * h
    rho = np.hypot(vertices[:, 0] - neck[0], (vertices[:, 2] - neck[2] - 0.01 * h) / 0.85)
    cuts = [np.minimum(neck_r - rho, vertices[:, 1] - (neck[1] - 0.075 * h)),  # the neck opening
            hem - vertices[:, 1]]                                             # the hem
    for side, sign in (("l", 1.0), ("r", -1.0)):
        sh, el = body.joint(f"{side}_shoulder"), body.joint(f"{side}_elbow")
        axis = (el - sh) / np.linalg.norm(el - sh)
        t = (vertices - sh) @ axis
        radial = np.linalg.norm((vertices - sh) - t[:, None] * axis, axis=1)
        outside = sign * vertices[:, 0] - (abs(float(sh[0])) + 0.03)  # never the torso's side
        cuts.append(np.minimum(np.minimum(t - sleeve, 0.09 * h - radial), outside))  # the sleeve ends
    return np.max(np.stack(cuts), axis=0)


def make_garment(body: SynthBody, kind: str, looseness: float = 0.03, resolution: float = 0.02,
                 sleeve_length: float = 0.5, length: float = 1.0, fit: str = "loose") -> Mesh:
    """A garment shell fitted to ``body`` in the capture pose.

    kind: 'tshirt' (loose, short sleeves) or 'dress' (cap sleeves, flared skirt to the knees);
    looseness: clearance from the body in metres (>= 0.01; loose fit: sleeves get 1.3x; resting fit: at the waist);
    resolution: target edge length in metres (0.02 gives about 2.6k vertices for the loose tshirt, 2.0k
    resting);
    sleeve_length: sleeve length as a fraction of the upper arm (tshirt; the dress uses a quarter of it);
    length: hem height scale (1 = hip for the tshirt, just above the knee for the dress; < 1 is longer);
    fit: 'loose' (the body's surface offset by the looseness, the sleeves by 1.3 times) or 'resting' (offset
    by :data:`RESTING_TOP_GAP` over the shoulders and chest, growing to ``looseness`` at the waist: the
    garment hangs from the shoulders); docs/synth.md has the measured clearances.
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
    v, f, uv, face_uv = _build(body, kind, float(looseness), float(resolution), float(sleeve_length), float(length),
                               fit)
    return Mesh(v, f, uv, face_uv, np.full(len(f), 2, np.int32), name=kind)


def _build(body: SynthBody, kind: str, looseness: float, resolution: float, sleeve_length: float, length: float,
           fit: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Garment arrays: vertices, faces, uv, face_uv."""
    joints, h = body.joints, body.height
    upper_arm = float(np.linalg.norm(body.joint("l_elbow") - body.joint("l_shoulder")))
    sleeve = upper_arm * (sleeve_length if kind == "tshirt" else sleeve_length * 0.25)
    hem = (0.47 if kind == "tshirt" else 0.28) * h * length
    cone = hip_cone(body, kind, hem)
    field = (_resting_field(body, cone, looseness, resolution) if fit == "resting"
             else _garment_field(body, cone, looseness))
    lo = joints.min(axis=0) - 0.3 * h
    hi = joints.max(axis=0) + 0.3 * h
    spacing = float(np.clip(resolution / 2.5, 0.006, 0.016))  # marching-cubes grid
    lo[1] = max(lo[1], hem - 0.1 * h) + 0.37 * spacing  # keep grid planes off the hem plane
    hi[1] = float(body.joint("neck")[1]) + 0.06  # above the shoulders, below the chin
    v, f = implicit.mesh_field(lambda p: np.maximum(field(p), np.maximum(lo[1] + 0.02 - p[:, 1],
                                                                          p[:, 1] - hi[1] + 0.02)),
                               lo, hi, spacing)
    v, f = implicit.clip_mesh(v, f, _cut_field(body, kind, v, sleeve, hem))
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
