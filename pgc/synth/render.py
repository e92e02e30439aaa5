"""Rendering the synthetic scene: path-traced colour and exact ray-cast ground truth per pixel (coverage
mask, segmentation, albedo, depth), through the ``scene_renderer`` role that the run configuration chooses
(``[scene_renderer]``; default: Mitsuba 3 on the CPU).

This module holds what does not depend on the renderer: the scene description (:class:`SceneGeometry`),
the labels, the sub-pixel rays of the ground truth and the reduction of their hits into layers (OpenCV
pixel convention of :class:`pgc.types.Camera`): mask = covered fraction, segmentation = the label covering
most samples, albedo = mean base colour over the covered samples (the BSDF's base colour; 0 where nothing
is hit), depth = mean camera z (metres) over the covered samples (0 where nothing is hit).
:func:`scene_renderer` builds the configuration's renderer; the functions that render take it as an argument.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pgc.synth.detail import DetailSurface
from pgc.synth.fabrics import Fibres
from pgc.texture.sample import sample_uv
from pgc.types import Camera, Material, Mesh

if TYPE_CHECKING:
    from pgc.config import RunConfig
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


def scene_renderer(cfg: RunConfig) -> SceneRenderer:
    """The scene renderer ``cfg`` chooses (``[scene_renderer]``), built with its options; none registered raises
    :class:`pgc.errors.PGCPluginError` naming the extra to install."""
    from pgc.errors import PGCPluginError

    if "scene_renderer" not in cfg.roles:
        raise PGCPluginError("no scene_renderer is registered (the synthetic scene is path traced by the "
                             "Mitsuba backend); install with: pip install 'pgc[mitsuba]'")
    return cfg.create("scene_renderer")


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
