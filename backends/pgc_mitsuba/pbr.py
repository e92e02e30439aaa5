"""The ``mitsuba`` PBR renderer: path-traced screen-space and texture-space rendering, material fitting.

Screen space: an exact OpenCV pinhole sensor (see :mod:`pgc_mitsuba.sensors`), RGBA film, emitters hidden
(black background, alpha = coverage). Texture space: one ray per covered texel of the UV atlas, starting a
small distance from the texel's surface point on the line to the camera centre and travelling back to that
point: the radiance leaving the texel toward the camera, with shadows and indirect light, whether or not
the texel is visible from the camera. (An origin offset along the normal instead shifts the hit laterally
by offset * tan(theta), which leaves the texel's triangle at grazing angles.) Large renders are split into passes
of at most ``max_samples_per_pass`` rays whose results are averaged (same estimator, bounded memory).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pgc.events import Reporter
from pgc.roles.pbr_renderer import MaterialFit, PBRRenderer
from pgc.roles.splat_renderer import RenderOutput
from pgc.types import Camera, Capture, Light, Material, Mesh
from pgc_mitsuba.runtime import mitsuba
from pgc_mitsuba.scene import scene_dict
from pgc_mitsuba.sensors import pinhole_sensor, ray_sensor
from pgc_mitsuba.specs_pbr import MitsubaPBROptions


class MitsubaPBRRenderer(PBRRenderer):
    """Path-traced PBR rendering with Mitsuba 3 (see module docstring)."""

    Options = MitsubaPBROptions
    options: MitsubaPBROptions

    def _scene(self, mesh: Mesh, material: Material, light: Light, occluder: Mesh | None = None,
               max_depth: int | None = None) -> Any:
        mi = mitsuba()
        integrator = {"type": "path", "max_depth": max_depth or self.options.max_depth, "hide_emitters": True}
        return mi.load_dict(scene_dict(mesh, material, light, integrator, occluder, self.options.occluder_albedo,
                                       self.options.smooth_normals))

    def _passes(self, rays: int, spp: int) -> list[int]:
        """Split ``spp`` samples of ``rays`` rays into passes of at most max_samples_per_pass rays."""
        n = max(1, math.ceil(rays * spp / self.options.max_samples_per_pass))
        n = min(n, spp)
        return [spp // n + (1 if i < spp % n else 0) for i in range(n)]

    def render(self, mesh: Mesh, material: Material, light: Light, camera: Camera,
               spp: int | None = None, occluder: Mesh | None = None, max_depth: int | None = None) -> RenderOutput:
        """Render ``mesh`` from ``camera``: linear RGB over black and alpha coverage. ``spp`` and
        ``max_depth`` override the options; ``occluder`` adds a grey Lambertian mesh that shadows and
        inter-reflects; pixels whose centre sees the occluder first are returned empty."""
        mi = mitsuba()
        scene = self._scene(mesh, material, light, occluder, max_depth)
        spp = spp or self.options.spp
        total = np.zeros((camera.height, camera.width, 4))
        for i, n in enumerate(self._passes(camera.width * camera.height, spp)):
            sensor = pinhole_sensor(camera, n)
            total += n * np.asarray(mi.render(scene, sensor=sensor, spp=n, seed=self.options.seed + i),
                                    dtype=np.float64)
        img = (total / spp).astype(np.float32)
        if occluder is not None:
            from pgc.texture.visibility import render_faces

            img *= (render_faces(mesh, camera, occluder=occluder).face_id >= 0)[..., None]
        return RenderOutput(color=np.ascontiguousarray(img[..., :3]), alpha=np.ascontiguousarray(img[..., 3]))

    def render_texture(self, mesh: Mesh, material: Material, light: Light, camera: Camera,
                       resolution: tuple[int, int], occluder: Mesh | None = None,
                       spp: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Radiance toward ``camera``'s centre at every texel centre: ((H, W, 3), (H, W) coverage).

        Coverage is the fraction of a texel's rays that found the surface (0 outside the charts);
        ``occluder`` shadows and inter-reflects (a grey Lambertian shape)."""
        from pgc.texture.atlas import texel_geometry

        mi = mitsuba()
        height, width = int(resolution[0]), int(resolution[1])
        geom = texel_geometry(mesh, height, width)
        valid = geom.valid
        points = geom.position[valid]
        to_cam = camera.center[None, :] - points
        to_cam /= np.maximum(np.linalg.norm(to_cam, axis=1, keepdims=True), 1e-12)
        diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0))) or 1.0
        origins = points + self.options.ray_offset * diag * to_cam
        scene = self._scene(mesh, material, light, occluder)
        spp = spp or self.options.spp
        chunk = max(1, self.options.max_samples_per_pass // spp)
        radiance = np.zeros((len(points), 4))
        for start in range(0, len(points), chunk):
            sl = slice(start, start + chunk)
            sensor = ray_sensor(origins[sl], -to_cam[sl], spp)
            img = np.asarray(mi.render(scene, sensor=sensor, spp=spp, seed=self.options.seed + start), np.float64)
            radiance[sl] = img.reshape(-1, img.shape[-1])
        out = np.zeros((height, width, 3), dtype=np.float32)
        cover = np.zeros((height, width), dtype=np.float32)
        out[valid] = radiance[:, :3]
        cover[valid] = radiance[:, 3]
        return out, cover

    def fit(self, capture: Capture, mesh: Mesh, material: Material, settings: Any = None,
            reporter: Reporter | None = None) -> MaterialFit:
        """Fit ``material.brdf``'s parameters and the constant light radiance (see :mod:`pgc_mitsuba.fit`)."""
        from pgc_mitsuba.fit import fit_material

        return fit_material(self, capture, mesh, material, settings, reporter)
