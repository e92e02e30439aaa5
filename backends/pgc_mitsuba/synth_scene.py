"""The ``scene_renderer`` role on Mitsuba 3 (LLVM variant, CPU): path-traced colour and exact ray-cast
ground truth of a synthetic scene (:class:`pgc.roles.scene_renderer.SceneGeometry`).

Colour: the ``path`` integrator, box pixel filter (a pixel's value is the mean radiance over its square, so
edges blend the person with the background by exact coverage), the named sampler seeded per call
(Mitsuba's LLVM rendering is deterministic for a fixed seed). Ground truth: one ``ray_intersect`` of the
rays of :func:`pgc.roles.scene_renderer.subpixel_rays`, reduced by
:func:`pgc.roles.scene_renderer.layers_from_samples`.

The garment's BSDF is :func:`pgc_mitsuba.bsdfs.material_to_bsdf` (the shared BRDF evaluation), wrapped in
Mitsuba's ``normalmap`` when the fabric has a weave, on the garment's near-field detail surface when there is
one (:mod:`pgc.synth.detail`); the body is Lambertian (Mitsuba ``diffuse``); fibres are ``linearcurve``
shapes (:mod:`pgc_mitsuba.fibres`): a fibre truth's layer shaded by Mitsuba's ``hair`` BSDF, a control's
sparse fibres by the garment's BRDF in the fibres' colour.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.roles.scene_renderer import SceneRenderer
from pgc.roles.scene_renderer import SceneGeometry, empty_layers, layers_from_samples, subpixel_rays
from pgc.types import BODY_LABEL, GARMENT_LABEL, Camera, Light, Material
from pgc_mitsuba.bsdfs import material_to_bsdf
from pgc_mitsuba.fibres import FIBRE_ID, fibre_shapes
from pgc_mitsuba.runtime import mesh_to_mitsuba, mitsuba
from pgc_mitsuba.scene import emitter_dict
from pgc_mitsuba.specs_scene import MitsubaSceneOptions


def sensor_dict(camera: Camera, spp: int, sampler: str = "independent") -> dict[str, Any]:
    """A Mitsuba perspective sensor equivalent to the OpenCV ``camera`` (square pixels required) with
    ``spp`` samples of the Mitsuba ``sampler`` per pixel."""
    mi = mitsuba()
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
    """The garment's BSDF scene-dict, wrapped in ``normalmap`` when there is a normal map (v up)."""
    bsdf = material_to_bsdf(material, two_sided=True)
    if normal_map is None:
        return bsdf
    mi = mitsuba()
    nm = mi.Bitmap(np.ascontiguousarray(np.asarray(normal_map, np.float32)[::-1]))  # rows: v up -> Mitsuba
    return {"type": "normalmap", "normalmap": {"type": "bitmap", "bitmap": nm, "raw": True,
                                               "filter_type": "bilinear"}, "bsdf": bsdf}


class MitsubaSceneRenderer(SceneRenderer):
    Options = MitsubaSceneOptions
    light_kinds = ("constant", "envmap")

    def build_scene(self, geometry: SceneGeometry | None, light: Light) -> tuple[Any, dict[str, int]]:
        mi = mitsuba()
        scene: dict[str, Any] = {"type": "scene", "integrator": {"type": "path", "max_depth": self.options.max_depth},
                                 "emitter": emitter_dict(light)}
        labels: dict[str, int] = {}
        if geometry is not None:
            g = geometry.garment
            if len(geometry.body_faces):
                scene["body"] = mesh_to_mitsuba(geometry.body_vertices, geometry.body_faces, name="body",
                                                vertex_normals=True,
                                                bsdf=mi.load_dict({"type": "diffuse", "reflectance": {
                                                    "type": "rgb", "value": list(geometry.skin_albedo)}}))
            surface = geometry.garment_surface()
            scene["garment"] = mesh_to_mitsuba(surface.vertices, surface.faces, name="garment", uv=surface.uv,
                                               face_uv=surface.face_uv, vertex_normals=True,
                                               bsdf=mi.load_dict(garment_bsdf(geometry.material, geometry.normal_map)))
            labels = {"body": BODY_LABEL, "garment": GARMENT_LABEL}
            if geometry.fibres is not None:
                shapes = fibre_shapes(geometry.fibres, g.vertices, g.faces, geometry.material)
                scene.update(shapes)
                labels.update(dict.fromkeys(shapes, GARMENT_LABEL))
        return mi.load_dict(scene), labels

    def render_color(self, scene: Any, camera: Camera, spp: int, seed: int, sampler: str = "independent"
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Linear RGB and the film's alpha (Mitsuba's ``rgba`` film: 1 for rays ending on a shape or an
        environment emitter)."""
        mi = mitsuba()
        sensor = mi.load_dict(sensor_dict(camera, spp, sampler))
        out = np.array(mi.render(scene, sensor=sensor, spp=int(spp), seed=int(seed)), dtype=np.float32)
        return np.ascontiguousarray(out[..., :3]), np.ascontiguousarray(out[..., 3])

    def ground_truth_layers(self, scene: Any, labels: dict[str, int], geometry: SceneGeometry | None,
                            camera: Camera, samples: int = 4) -> dict[str, np.ndarray]:
        import drjit as dr

        mi = mitsuba()
        if geometry is None:
            return empty_layers(camera)
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
            label[hit] = labels.get(shape.id(), BODY_LABEL)
        t = np.array(si.t, dtype=np.float64)
        uv = np.stack([np.array(si.uv.x), np.array(si.uv.y)], axis=1)
        z = np.where(valid, t * (d @ camera.R[2]), 0.0)
        on_fibre = None
        if geometry.fibres is not None:
            on_fibre = np.zeros(len(o), bool)
            for shape in scene.shapes():
                if shape.id().startswith(FIBRE_ID):
                    on_fibre |= np.array(si.shape == mi.ShapePtr(shape), dtype=bool) & valid
        return layers_from_samples(geometry, camera, samples, valid, label, z, uv, on_fibre)
