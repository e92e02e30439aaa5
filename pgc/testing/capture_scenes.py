"""Small captures made in-process for tests and benchmarks (no generator, no path tracer).

:func:`make_capture`: a body-like blob (torso, head, arms in an A-pose, legs; about 1.7 m tall, +Y up, feet
at y = 0) with a 'garment' band on the torso, a solid procedural texture (stripes and value noise of a few
centimetres, so photo-consistency has texture), Lambertian shading under a fixed directional light plus
ambient (view independent), rendered with 2x2 supersampling through cameras on a dome: the scene of the
reconstruction and splat-fit tests.

:func:`textured_box_capture`: a textured cube seen by exactly posed cameras (the calibrator's scene).

:func:`strip_ground_truth`: a copy of a capture folder as a user brings one: images, masks, labels, cameras,
nothing the generator knows.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from pgc.geometry.raster import rasterize
from pgc.geometry.surface_nets import surface_nets
from pgc.types import BODY_LABEL, DEFAULT_LABELS, GARMENT_LABEL, Camera, Capture, Mesh, View, look_at_pose


def look_at(center: np.ndarray, target: np.ndarray, width: int, height: int, fov_y_deg: float,
            name: str) -> Camera:
    """An OpenCV camera at ``center`` looking at ``target`` with world +Y up, ``fov_y_deg`` vertical field of
    view and the principal point at the image centre."""
    R, t = look_at_pose(center, target)
    f = 0.5 * height / np.tan(np.radians(fov_y_deg) / 2)
    K = np.array([[f, 0, width / 2], [0, f, height / 2], [0, 0, 1]])
    return Camera(K, R, t, width, height, name)


def dome_cameras(count: int, size: int = 128, radius: float = 3.0, target_y: float = 0.9,
                 fov_y_deg: float = 40.0) -> list[Camera]:
    """``count`` cameras on rings of a half dome (elevations -10..50 degrees) looking at the person."""
    rings = [(-10.0, 0.0), (15.0, 0.5), (45.0, 0.25)]
    per_ring = np.array_split(np.arange(count), len(rings))
    cams = []
    target = np.array([0.0, target_y, 0.0])
    for (elev, phase), idx in zip(rings, per_ring):
        for j, i in enumerate(idx):
            az = 2 * np.pi * (j + phase) / max(len(idx), 1)
            e = np.radians(elev)
            c = target + radius * np.array([np.cos(e) * np.sin(az), np.sin(e), np.cos(e) * np.cos(az)])
            cams.append(look_at(c, target, size, size, fov_y_deg, f"cam{i:03d}"))
    return cams


def _capsule(p: np.ndarray, a, b, r: float) -> np.ndarray:
    a, b = np.asarray(a, float), np.asarray(b, float)
    ab = b - a
    t = np.clip(((p - a) @ ab) / (ab @ ab), 0, 1)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1) - r


def _smooth_min(a: np.ndarray, b: np.ndarray, k: float = 0.04) -> np.ndarray:
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0, 1)
    return b * (1 - h) + a * h - k * h * (1 - h)


def body_sdf(p: np.ndarray) -> np.ndarray:
    """Signed distance (metres, approximately) of the blob body."""
    torso = np.linalg.norm((p - [0, 1.2, 0]) / [0.19, 0.33, 0.12], axis=1) - 1.0
    torso *= 0.12
    d = _smooth_min(torso, np.linalg.norm(p - [0, 1.62, 0], axis=1) - 0.11)
    d = _smooth_min(d, _capsule(p, [0, 1.45, 0], [0, 1.55, 0], 0.05))
    for s in (-1.0, 1.0):
        d = _smooth_min(d, _capsule(p, [s * 0.19, 1.42, 0], [s * 0.55, 0.98, 0], 0.05))
        d = _smooth_min(d, _capsule(p, [s * 0.1, 0.92, 0], [s * 0.13, 0.08, 0.0], 0.075))
    return d


def body_mesh(spacing: float = 0.015) -> Mesh:
    """The labelled blob mesh: label 2 (garment) on the torso band 0.95 m < y < 1.45 m, |x| < 0.24 m."""
    lo, hi = np.array([-0.75, -0.05, -0.3]), np.array([0.75, 1.8, 0.3])
    n = np.ceil((hi - lo) / spacing).astype(int) + 1
    axes = [lo[i] + spacing * np.arange(n[i]) for i in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    field = np.maximum(body_sdf(pts), 0.0 - pts[:, 1]).reshape(n)  # flat soles at y = 0
    v, f = surface_nets(field, lo, spacing)
    c = v[f].mean(1)
    garment = (c[:, 1] > 0.95) & (c[:, 1] < 1.45) & (np.abs(c[:, 0]) < 0.24)
    return Mesh(v, f, face_labels=np.where(garment, GARMENT_LABEL, BODY_LABEL), name="blob")


def albedo(points: np.ndarray, labels: np.ndarray, seed: int = 0) -> np.ndarray:
    """(N, 3) linear RGB base colour: a solid texture of stripes and noise, different per label."""
    rng = np.random.default_rng(seed)
    freq = rng.normal(size=(6, 3))
    freq *= (2 * np.pi / rng.uniform(0.02, 0.06, size=6))[:, None] / np.linalg.norm(freq, axis=1, keepdims=True)
    phase = rng.uniform(0, 2 * np.pi, 6)
    noise = np.sin(points @ freq.T + phase).mean(1)  # in [-1, 1]
    stripes = 0.5 + 0.5 * np.sign(np.sin(points[:, 1] * 2 * np.pi / 0.05))
    garment = np.array([0.15, 0.25, 0.6]) + 0.35 * stripes[:, None] * np.array([0.9, 0.8, 0.2])
    skin = np.array([0.55, 0.38, 0.3]) * np.ones((len(points), 1))
    base = np.where((labels == GARMENT_LABEL)[:, None], garment, skin)
    return np.clip(base * (1.0 + 0.45 * noise[:, None]), 0.02, 1.0)


def render_view(mesh: Mesh, camera: Camera, background: float = 0.2, supersample: int = 2) -> View:
    """One view: image, soft mask (coverage), segmentation (pixel-centre label) and depth (extras)."""
    light = np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5])
    big = camera.scaled(supersample)
    r = rasterize(big, mesh.vertices, mesh.faces)
    hit = r.face_id >= 0
    fid = r.face_id[hit]
    pts = np.einsum("nk,nkj->nj", r.bary[hit], mesh.vertices[mesh.faces[fid]])
    shade = 0.35 + 0.65 * np.clip(mesh.face_normals()[fid] @ light, 0, None)
    img = np.full((big.height, big.width, 3), background)
    img[hit] = albedo(pts, mesh.face_labels[fid]) * shade[:, None]
    s = supersample
    h, w = camera.height, camera.width
    img = img.reshape(h, s, w, s, 3).mean((1, 3))
    mask = hit.reshape(h, s, w, s).mean((1, 3))
    small = rasterize(camera, mesh.vertices, mesh.faces)
    seg = np.where(small.face_id >= 0, mesh.face_labels[np.maximum(small.face_id, 0)], 0)
    return View(camera, img.astype(np.float32), mask.astype(np.float32), seg.astype(np.uint8),
                np.full((h, w, 3), background, np.float32), extras={"depth": small.depth.astype(np.float32)})


def make_capture(mesh: Mesh | None = None, views: int = 16, size: int = 128) -> tuple[Capture, Mesh]:
    """A capture of ``mesh`` (default :func:`body_mesh`) from ``views`` dome cameras, and the mesh."""
    mesh = mesh if mesh is not None else body_mesh()
    views_ = [render_view(mesh, cam) for cam in dome_cameras(views, size)]
    return Capture(views_, labels=dict(DEFAULT_LABELS)), mesh


def textured_box_capture(views: int = 8, size: int = 192) -> Capture:
    """A capture of a 0.8 m cube with a multi-scale solid noise texture (SIFT finds blobs on it) from
    ``views`` cameras 20 degrees apart on an arc 2.2 m from its centre, with exact poses."""
    n, half = 8, 0.4
    g = np.linspace(-half, half, n + 1)
    vertices, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = np.meshgrid(g, g, indexing="ij")
            p = np.zeros(u.shape + (3,))
            p[..., axis], p[..., (axis + 1) % 3], p[..., (axis + 2) % 3] = sign * half, u, v
            idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1) + sum(len(x) for x in vertices)
            q = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 4)
            f = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
            faces.append(f if sign > 0 else f[:, ::-1])
            vertices.append(p.reshape(-1, 3))
    box = Mesh(np.concatenate(vertices), np.concatenate(faces))
    rng = np.random.default_rng(0)
    freq = rng.normal(size=(3, 16, 3))
    freq *= (2 * np.pi / rng.uniform(0.04, 0.15, size=(3, 16)))[..., None] / np.linalg.norm(freq, axis=-1,
                                                                                             keepdims=True)
    phase = rng.uniform(0, 2 * np.pi, (3, 16))
    out = []
    for i in range(views):
        a, e = np.radians(20.0 * i), np.radians(25.0)
        centre = 2.2 * np.array([np.cos(e) * np.sin(a), np.sin(e), np.cos(e) * np.cos(a)])
        cam = look_at(centre, np.zeros(3), size, size, 40.0, f"v{i}")
        r = rasterize(cam, box.vertices, box.faces)
        hit = r.face_id >= 0
        pts = np.einsum("nk,nkj->nj", r.bary[hit], box.vertices[box.faces[r.face_id[hit]]])
        image = np.full((size, size, 3), 0.5, np.float32)
        image[hit] = np.stack([0.5 + 0.45 * np.tanh(4 * np.sin(pts @ freq[c].T + phase[c]).mean(1))
                               for c in range(3)], -1)
        out.append(View(cam, image, hit.astype(np.float32), hit.astype(np.uint8)))
    return Capture(out)


GROUND_TRUTH_PARTS = ("ground_truth", "extras", "light", "contact_sheet.png")
"""What of a synthetic capture folder a real capture does not have."""
GROUND_TRUTH_KEYS = ("pgc_metadata", "pgc_light")
"""Top-level transforms.json keys written from the generator's knowledge (per frame: ``pgc_extras``)."""


def strip_ground_truth(capture: str | Path, out: str | Path) -> Path:
    """Copy the capture folder ``capture`` to ``out`` without its ground truth (:data:`GROUND_TRUTH_PARTS`), its
    extra layers and recorded light (:data:`GROUND_TRUTH_KEYS`): transforms.json, images, masks, segmentation
    and backgrounds only, as a user's own capture."""
    capture, out = Path(capture), Path(out)
    shutil.copytree(capture, out, ignore=lambda folder, names: [n for n in names if Path(folder) == capture
                                                                and n in GROUND_TRUTH_PARTS])
    doc = json.loads((out / "transforms.json").read_text())
    for key in GROUND_TRUTH_KEYS:
        doc.pop(key, None)
    for frame in doc["frames"]:
        frame.pop("pgc_extras", None)
    (out / "transforms.json").write_text(json.dumps(doc, indent=1))
    return out
