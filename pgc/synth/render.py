"""Rendering the synthetic scene with Mitsuba 3 (LLVM variant, CPU): path-traced colour, and exact
ray-cast ground truth per pixel (coverage mask, segmentation, albedo, depth).

Colour: the ``path`` integrator, box pixel filter (a pixel's value is the mean radiance over its square, so
edges blend the person with the background by exact coverage), an independent sampler seeded per view
(Mitsuba's LLVM rendering is deterministic for a fixed seed). Ground-truth layers come from our own rays
through ``s x s`` stratified sub-pixel positions (OpenCV pixel convention of :class:`pgc.types.Camera`):
mask = covered fraction, segmentation = the label covering most samples, albedo = mean base colour over
the covered samples (the BSDF's base colour; 0 where nothing is hit), depth = mean camera z (metres) over
the covered samples (0 where nothing is hit).

The garment's BSDF is :func:`pgc_mitsuba.bsdfs.material_to_bsdf` (the shared BRDF evaluation), wrapped in
Mitsuba's ``normalmap`` when the fabric has a weave; the body is Lambertian (Mitsuba ``diffuse``).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.synth.fabrics import Fibres
from pgc.texture.sample import sample_uv
from pgc.types import Camera, Light, Material, Mesh

SKIN_ALBEDO = (0.56, 0.38, 0.29)
"""Linear RGB albedo of the (Lambertian) body."""
LABEL_BACKGROUND, LABEL_BODY, LABEL_GARMENT = 0, 1, 2


@dataclass
class SceneGeometry:
    """What is in front of the cameras: the body (may have no faces), the garment with its appearance,
    optional fibres."""

    body_vertices: np.ndarray
    body_faces: np.ndarray
    garment: Mesh
    material: Material
    normal_map: np.ndarray | None = None
    fibres: Fibres | None = None
    skin_albedo: tuple[float, float, float] = SKIN_ALBEDO


def _mi():
    from pgc_mitsuba.runtime import mitsuba

    return mitsuba()


def sensor_dict(camera: Camera, spp: int, sampler: str = "independent") -> dict[str, Any]:
    """A Mitsuba perspective sensor equivalent to the OpenCV ``camera`` (square pixels required) with
    ``spp`` samples of the Mitsuba ``sampler`` per pixel."""
    mi = _mi()
    if abs(camera.fx - camera.fy) > 1e-6 * camera.fx or abs(camera.K[0, 1]) > 1e-9:
        raise PGCDataError(f"camera '{camera.name}': rendering needs square pixels and no skew "
                           f"(fx={camera.fx}, fy={camera.fy})")
    w, h = camera.width, camera.height
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2] = -camera.R[0], -camera.R[1], camera.R[2]  # Mitsuba: x left, y up
    c2w[:3, 3] = camera.center
    return {"type": "perspective", "fov_axis": "x", "fov": float(np.degrees(2 * np.arctan(w / (2 * camera.fx)))),
            "principal_point_offset_x": float((camera.K[0, 2] - w / 2) / w),
            "principal_point_offset_y": float((camera.K[1, 2] - h / 2) / h),
            "near_clip": 0.01, "far_clip": 100.0,
            "to_world": mi.ScalarTransform4f(c2w.tolist()),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgba"},
            "sampler": {"type": sampler, "sample_count": int(spp)}}


def garment_bsdf(material: Material, normal_map: np.ndarray | None) -> dict[str, Any]:
    from pgc_mitsuba.bsdfs import material_to_bsdf

    bsdf = material_to_bsdf(material, two_sided=True)
    if normal_map is None:
        return bsdf
    mi = _mi()
    nm = mi.Bitmap(np.ascontiguousarray(np.asarray(normal_map, np.float32)[::-1]))  # rows: v up -> Mitsuba
    return {"type": "normalmap", "normalmap": {"type": "bitmap", "bitmap": nm, "raw": True,
                                               "filter_type": "bilinear"}, "bsdf": bsdf}


def fibre_shape(fibres: Fibres, garment_vertices: np.ndarray, garment_faces: np.ndarray,
                material: Material) -> Any:
    """A Mitsuba ``linearcurve`` shape of the fibres on the given garment vertices."""
    from pgc_mitsuba.bsdfs import material_to_bsdf

    mi = _mi()
    pts = fibres.control_points(garment_vertices, garment_faces)
    radius = np.full(pts.shape[:2] + (1,), fibres.radius)
    radius[:, -1] *= 0.5  # tapered tips
    rows = np.concatenate([pts, radius], axis=-1)
    text = "\n\n".join("\n".join(" ".join(f"{x:.7g}" for x in p) for p in curve) for curve in rows)
    fibre_material = Material(material.brdf, dict(material.params, base_color=fibres.color.tolist()))
    fd, path = tempfile.mkstemp(suffix=".txt", prefix="pgc_fibres_")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text + "\n")
        return mi.load_dict({"type": "linearcurve", "filename": path, "bsdf": material_to_bsdf(fibre_material)})
    finally:
        os.unlink(path)


def build_scene(geometry: SceneGeometry | None, light: Light, max_depth: int = 8) -> tuple[Any, dict[str, int]]:
    """The Mitsuba scene (path integrator) and a map from shape id ('body', 'garment', 'fibres') to
    segmentation label; ``geometry`` None gives the empty dome."""
    from pgc_mitsuba.runtime import mesh_to_mitsuba
    from pgc_mitsuba.scene import emitter_dict

    mi = _mi()
    scene: dict[str, Any] = {"type": "scene", "integrator": {"type": "path", "max_depth": max_depth},
                             "emitter": emitter_dict(light)}
    labels: dict[str, int] = {}
    if geometry is not None:
        g = geometry.garment
        if len(geometry.body_faces):
            scene["body"] = mesh_to_mitsuba(geometry.body_vertices, geometry.body_faces, name="body",
                                            vertex_normals=True,
                                            bsdf=mi.load_dict({"type": "diffuse", "reflectance": {
                                                "type": "rgb", "value": list(geometry.skin_albedo)}}))
        scene["garment"] = mesh_to_mitsuba(g.vertices, g.faces, name="garment", uv=g.uv, face_uv=g.face_uv,
                                           vertex_normals=True,
                                           bsdf=mi.load_dict(garment_bsdf(geometry.material, geometry.normal_map)))
        labels = {"body": LABEL_BODY, "garment": LABEL_GARMENT}
        if geometry.fibres is not None:
            scene["fibres"] = fibre_shape(geometry.fibres, g.vertices, g.faces, geometry.material)
            labels["fibres"] = LABEL_GARMENT
    loaded = mi.load_dict(scene)
    return loaded, labels


def render_color(scene: Any, camera: Camera, spp: int, seed: int, sampler: str = "independent"
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Path-traced linear RGB (H, W, 3) and the film's alpha (H, W) (box-filtered hit coverage)."""
    mi = _mi()
    sensor = mi.load_dict(sensor_dict(camera, spp, sampler))
    out = np.array(mi.render(scene, sensor=sensor, spp=int(spp), seed=int(seed)), dtype=np.float32)
    return np.ascontiguousarray(out[..., :3]), np.ascontiguousarray(out[..., 3])


def subpixel_rays(camera: Camera, s: int) -> tuple[np.ndarray, np.ndarray]:
    """World ray origins and unit directions (H, W, s*s, 3) through s x s stratified sub-pixel centres."""
    off = (np.arange(s) + 0.5) / s
    oy, ox = np.meshgrid(off, off, indexing="ij")
    ys, xs = np.mgrid[0:camera.height, 0:camera.width].astype(np.float64)
    px = xs[..., None] + ox.reshape(-1)
    py = ys[..., None] + oy.reshape(-1)
    pix = np.stack([px, py, np.ones_like(px)], axis=-1)
    d = pix @ np.linalg.inv(camera.K).T @ camera.R
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.broadcast_to(camera.center, d.shape), d


def ground_truth_layers(scene: Any, labels: dict[str, int], geometry: SceneGeometry | None, camera: Camera,
                        samples: int = 4) -> dict[str, np.ndarray]:
    """Exact per-pixel layers by ray casting ``samples`` x ``samples`` rays per pixel:
    'mask' (H, W) coverage, 'segmentation' (H, W) uint8, 'albedo' (H, W, 3), 'depth' (H, W) metres,
    'garment_coverage' (H, W) the fraction covered by the garment."""
    import drjit as dr


    mi = _mi()
    h, w = camera.height, camera.width
    n = samples * samples
    if geometry is None:
        return {"mask": np.zeros((h, w), np.float32), "segmentation": np.zeros((h, w), np.uint8),
                "albedo": np.zeros((h, w, 3), np.float32), "depth": np.zeros((h, w), np.float32),
                "garment_coverage": np.zeros((h, w), np.float32)}
    o, d = subpixel_rays(camera, samples)
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    ray = mi.Ray3f(mi.Point3f(*[mi.Float(o[:, k].astype(np.float32)) for k in range(3)]),
                   mi.Vector3f(*[mi.Float(d[:, k].astype(np.float32)) for k in range(3)]))
    si = scene.ray_intersect(ray)
    dr.eval(si.t, si.uv, si.shape)  # one kernel; the conversions below would otherwise re-trace the rays
    valid = np.array(si.is_valid(), dtype=bool)
    label = np.zeros(len(o), np.uint8)
    for shape in scene.shapes():
        hit = np.array(si.shape == mi.ShapePtr(shape), dtype=bool) & valid
        label[hit] = labels.get(shape.id(), LABEL_BODY)
    t = np.array(si.t, dtype=np.float64)
    uv = np.stack([np.array(si.uv.x), np.array(si.uv.y)], axis=1)
    z = np.where(valid, t * (d @ camera.R[2]), 0.0)
    albedo = np.zeros((len(o), 3))
    albedo[label == LABEL_BODY] = geometry.skin_albedo
    garment_hit = label == LABEL_GARMENT
    surface = garment_hit.copy()
    if geometry.fibres is not None:
        fibre_ptr = [s for s in scene.shapes() if s.id() == "fibres"]
        on_fibre = np.array(si.shape == mi.ShapePtr(fibre_ptr[0]), dtype=bool) & valid
        albedo[on_fibre] = geometry.fibres.color
        surface &= ~on_fibre
    albedo[surface] = sample_uv(geometry.material.base_color, uv[surface]) \
        if geometry.material.base_color is not None else geometry.material.params.get("base_color", 0.5)
    label, z, albedo, valid = (label.reshape(h, w, n), z.reshape(h, w, n), albedo.reshape(h, w, n, 3),
                               valid.reshape(h, w, n))
    hits = valid.sum(axis=2)
    counts = np.stack([(label == k).sum(axis=2) for k in (LABEL_BACKGROUND, LABEL_BODY, LABEL_GARMENT)], axis=-1)
    counts[..., 0] = n - hits
    safe = np.maximum(hits, 1)
    return {"mask": (hits / n).astype(np.float32),
            "segmentation": np.argmax(counts, axis=-1).astype(np.uint8),
            "albedo": (albedo.sum(axis=2) / safe[..., None]).astype(np.float32),
            "depth": (z.sum(axis=2) / safe).astype(np.float32),
            "garment_coverage": (counts[..., LABEL_GARMENT] / n).astype(np.float32)}

