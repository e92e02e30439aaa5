"""Role ``scene_renderer``: path-traced images and exact ground-truth layers of a synthetic scene.

Contract
- :meth:`SceneRenderer.build_scene` turns a :class:`SceneGeometry` (body, garment with its
  material and optional normal map, optional fibres; world metres) and a :class:`pgc.types.Light` into an
  opaque scene object of the implementation, and a map from its shape ids to segmentation labels
  (:data:`pgc.types.BODY_LABEL` / :data:`pgc.types.GARMENT_LABEL`). ``geometry`` None is the empty scene: the
  light only.
- :meth:`SceneRenderer.render_color` renders linear RGB (H, W, 3) float32 and the film's alpha (H, W) float32
  in [0, 1] for a :class:`pgc.types.Camera` (OpenCV convention, square pixels) with ``spp`` samples per
  pixel, box pixel filter; the same ``seed`` gives the same image. Rays that miss every shape see the
  environment light, so alpha (the fraction of rays ending on a shape or the environment) is 1 under the
  environment lights of :class:`pgc.types.Light`; coverage is the ground truth's 'mask'. ``sampler`` names the pixel
  sampler ("independent", "stratified", "multijitter", "ldsampler", ...).
- :meth:`SceneRenderer.ground_truth_layers` is exact up to the sub-pixel grid: rays through ``samples`` x
  ``samples`` stratified sub-pixel centres (pixel (0, 0) covers [0, 1)^2) give 'mask' (H, W) the covered
  fraction, 'segmentation' (H, W) uint8 the label covering most samples (background 0), 'albedo' (H, W, 3)
  the mean base colour over covered samples (0 where nothing is hit), 'depth' (H, W) the mean camera z in
  metres over covered samples (0 where nothing is hit), 'garment_coverage' (H, W) the garment's fraction
  (:func:`layers_from_samples` turns per-sample hits into these layers).
- :attr:`SceneRenderer.light_kinds` names the kinds of :class:`pgc.types.Light` it renders: ``"constant"``
  (radiance only) always; ``"envmap"`` (a latitude-longitude map turned ``rotation_deg`` about +Y) when it
  declares it. ``pgc eval`` refuses to render ground truth under a kind that is not declared.
- Every output is finite; outputs of one implementation are deterministic for fixed inputs.

The scene description (:class:`SceneGeometry`), the sub-pixel rays of the ground truth (:func:`subpixel_rays`)
and the reduction of their hits into layers (:func:`layers_from_samples`) are the same for every implementation
and live here (OpenCV pixel convention of :class:`pgc.types.Camera`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgc.geometry.embedded import DetailSurface
from pgc.geometry.fibres import Fibres
from pgc.roles._base import RoleImplementation
from pgc.texture.sample import sample_uv
from pgc.types import BACKGROUND_LABEL, BODY_LABEL, GARMENT_LABEL, Camera, Light, Material, Mesh

SKIN_ALBEDO = (0.56, 0.38, 0.29)
"""Linear RGB albedo of the (Lambertian) body."""


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
    albedo[label == BODY_LABEL] = geometry.skin_albedo
    garment_hit = label == GARMENT_LABEL
    surface = garment_hit.copy()
    if on_fibre is not None:
        albedo[on_fibre] = geometry.fibres.color
        surface &= ~on_fibre
    albedo[surface] = sample_uv(geometry.material.base_color, uv[surface]) \
        if geometry.material.base_color is not None else geometry.material.params.get("base_color", 0.5)
    label, z, albedo, valid = (label.reshape(h, w, n), z.reshape(h, w, n), albedo.reshape(h, w, n, 3),
                               valid.reshape(h, w, n))
    hits = valid.sum(axis=2)
    counts = np.stack([(label == k).sum(axis=2) for k in (BACKGROUND_LABEL, BODY_LABEL, GARMENT_LABEL)], axis=-1)
    counts[..., 0] = n - hits
    safe = np.maximum(hits, 1)
    return {"mask": (hits / n).astype(np.float32),
            "segmentation": np.argmax(counts, axis=-1).astype(np.uint8),
            "albedo": (albedo.sum(axis=2) / safe[..., None]).astype(np.float32),
            "depth": (z.sum(axis=2) / safe).astype(np.float32),
            "garment_coverage": (counts[..., GARMENT_LABEL] / n).astype(np.float32)}


class SceneRenderer(RoleImplementation, ABC):
    role = "scene_renderer"
    light_kinds: tuple[str, ...] = ("constant",)
    """The :class:`pgc.types.Light` kinds this renderer reproduces: ``"constant"``, and ``"envmap"`` if declared."""

    @abstractmethod
    def build_scene(self, geometry: SceneGeometry | None, light: Light) -> tuple[Any, dict[str, int]]:
        """The implementation's scene of ``geometry`` under ``light``, and its shape id -> label map."""

    @abstractmethod
    def render_color(self, scene: Any, camera: Camera, spp: int, seed: int, sampler: str = "independent"
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Path-traced linear RGB (H, W, 3) and alpha (H, W) of ``scene`` seen by ``camera``."""

    @abstractmethod
    def ground_truth_layers(self, scene: Any, labels: dict[str, int], geometry: SceneGeometry | None,
                            camera: Camera, samples: int = 4) -> dict[str, np.ndarray]:
        """Exact per-pixel layers ('mask', 'segmentation', 'albedo', 'depth', 'garment_coverage')."""
