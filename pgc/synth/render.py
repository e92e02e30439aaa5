"""Rendering the synthetic scene: path-traced colour and exact ray-cast ground truth per pixel (coverage
mask, segmentation, albedo, depth), through the ``scene_renderer`` role (default: Mitsuba 3 on the CPU,
``[scene_renderer]`` in the run configuration).

This module holds what does not depend on the renderer: the scene description (:class:`SceneGeometry`),
the labels, the sub-pixel rays of the ground truth and the reduction of their hits into layers (OpenCV
pixel convention of :class:`pgc.types.Camera`): mask = covered fraction, segmentation = the label covering
most samples, albedo = mean base colour over the covered samples (the BSDF's base colour; 0 where nothing
is hit), depth = mean camera z (metres) over the covered samples (0 where nothing is hit).
:func:`build_scene`, :func:`render_color` and :func:`ground_truth_layers` call the configured renderer.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from pgc.synth.detail import DetailSurface
from pgc.synth.fabrics import Fibres
from pgc.texture.sample import sample_uv
from pgc.types import Camera, Light, Material, Mesh

if TYPE_CHECKING:
    from pgc.roles.scene_renderer import SceneRenderer

SKIN_ALBEDO = (0.56, 0.38, 0.29)
"""Linear RGB albedo of the (Lambertian) body."""
LABEL_BACKGROUND, LABEL_BODY, LABEL_GARMENT = 0, 1, 2


@dataclass
class SceneGeometry:
    """What is in front of the cameras: the body (may have no faces), the garment with its appearance,
    optional fibres, optional near-field detail (rendered in place of the garment's own triangles)."""

    body_vertices: np.ndarray
    body_faces: np.ndarray
    garment: Mesh
    material: Material
    normal_map: np.ndarray | None = None
    fibres: Fibres | None = None
    skin_albedo: tuple[float, float, float] = SKIN_ALBEDO
    detail: DetailSurface | None = None

    def garment_surface(self) -> Mesh:
        """The garment surface that is rendered: the detail surface on the garment's vertices, or the
        garment itself."""
        if self.detail is None:
            return self.garment
        return self.detail.mesh(self.garment.vertices)


@lru_cache(maxsize=1)
def scene_renderer() -> SceneRenderer:
    """The ``scene_renderer`` of the default configuration, created once per process through the registry
    (an unavailable one raises :class:`pgc.errors.PGCPluginError` naming the extra to install)."""
    from pgc.config import resolve
    from pgc.errors import PGCPluginError
    from pgc.registry import default_registry

    cfg = resolve(None, default_registry(), require_available=False)
    if "scene_renderer" not in cfg.roles:
        raise PGCPluginError("no scene_renderer is registered (the synthetic scene is path traced by the "
                             "Mitsuba backend); install with: pip install 'pgc[mitsuba]'")
    return cfg.create("scene_renderer")


def build_scene(geometry: SceneGeometry | None, light: Light) -> tuple[Any, dict[str, int]]:
    """The renderer's scene and a map from shape id ('body', 'garment', 'fibres') to segmentation label;
    ``geometry`` None gives the empty dome."""
    return scene_renderer().build_scene(geometry, light)


def render_color(scene: Any, camera: Camera, spp: int, seed: int, sampler: str = "independent"
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Path-traced linear RGB (H, W, 3) and the film's alpha (H, W) (1 where rays end on a shape or the
    environment: everywhere under an environment light)."""
    return scene_renderer().render_color(scene, camera, spp, seed, sampler)


def ground_truth_layers(scene: Any, labels: dict[str, int], geometry: SceneGeometry | None, camera: Camera,
                        samples: int = 4) -> dict[str, np.ndarray]:
    """Exact per-pixel layers by ray casting ``samples`` x ``samples`` rays per pixel:
    'mask' (H, W) coverage, 'segmentation' (H, W) uint8, 'albedo' (H, W, 3), 'depth' (H, W) metres,
    'garment_coverage' (H, W) the fraction covered by the garment."""
    return scene_renderer().ground_truth_layers(scene, labels, geometry, camera, samples)


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


def empty_layers(camera: Camera) -> dict[str, np.ndarray]:
    """The ground-truth layers of a view that sees nothing (every layer zero)."""
    h, w = camera.height, camera.width
    return {"mask": np.zeros((h, w), np.float32), "segmentation": np.zeros((h, w), np.uint8),
            "albedo": np.zeros((h, w, 3), np.float32), "depth": np.zeros((h, w), np.float32),
            "garment_coverage": np.zeros((h, w), np.float32)}


def layers_from_samples(geometry: SceneGeometry, camera: Camera, samples: int, valid: np.ndarray,
                        label: np.ndarray, z: np.ndarray, uv: np.ndarray,
                        on_fibre: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Ground-truth layers from the hits of the rays of :func:`subpixel_rays` (flattened, H*W*s*s each):
    ``valid`` bool hit, ``label`` uint8 segmentation label of the hit shape, ``z`` camera z (metres, 0 where
    missed), ``uv`` (N, 2) surface UV of the hit, ``on_fibre`` bool (hits on fibres; None without fibres)."""
    h, w = camera.height, camera.width
    n = samples * samples
    albedo = np.zeros((len(valid), 3))
    albedo[label == LABEL_BODY] = geometry.skin_albedo
    garment_hit = label == LABEL_GARMENT
    surface = garment_hit.copy()
    if on_fibre is not None:
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
