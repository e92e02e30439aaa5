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

import hashlib
import json
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


def scene_fingerprint(mesh: Mesh, material: Material, light: Light, occluder: Mesh | None, max_depth: int) -> bytes:
    """A digest of everything :func:`pgc_mitsuba.scene.scene_dict` reads (array contents included, so arrays
    changed in place give another digest)."""
    h = hashlib.blake2b(digest_size=20)

    def add(value: Any) -> None:
        if isinstance(value, np.ndarray):
            h.update(f"{value.dtype.str}{value.shape}".encode())
            h.update(np.ascontiguousarray(value).data)
        else:
            h.update(repr(value).encode())

    for m in (mesh, occluder):
        for value in (None,) if m is None else (m.vertices, m.faces, m.uv, m.face_uv):
            add(None if value is None else np.asarray(value))
    add(material.brdf)
    add(json.dumps(material.params, sort_keys=True, default=lambda x: np.asarray(x).tolist()))
    add(None if material.base_color is None else np.asarray(material.base_color))
    add(np.asarray(light.radiance, np.float64))
    add(None if light.envmap is None else np.asarray(light.envmap))
    add((float(light.rotation_deg), int(max_depth)))
    return h.digest()


class MitsubaPBRRenderer(PBRRenderer):
    """Path-traced PBR rendering with Mitsuba 3 (see module docstring)."""

    Options = MitsubaPBROptions
    options: MitsubaPBROptions

    _last_scene: tuple[bytes, Any] | None = None

    def _scene(self, mesh: Mesh, material: Material, light: Light, occluder: Mesh | None = None,
               max_depth: int | None = None) -> Any:
        """The Mitsuba scene of these inputs. The last scene is kept and reused while the inputs are equal (a
        garment state is rendered from several cameras, in screen and texture space): building it costs about
        a fifth of a 64-spp render; the images are the same either way."""
        mi = mitsuba()
        depth = max_depth or self.options.max_depth
        key = scene_fingerprint(mesh, material, light, occluder, depth)
        if self._last_scene is not None and self._last_scene[0] == key:
            return self._last_scene[1]
        integrator = {"type": "path", "max_depth": depth, "hide_emitters": True}
        scene = mi.load_dict(scene_dict(mesh, material, light, integrator, occluder, self.options.occluder_albedo,
                                        self.options.smooth_normals))
        self._last_scene = (key, scene)
        return scene

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
