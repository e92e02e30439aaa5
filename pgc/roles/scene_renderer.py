"""Role ``scene_renderer``: path-traced images and exact ground-truth layers of a synthetic scene.

Contract
- :meth:`SceneRenderer.build_scene` turns a :class:`pgc.synth.render.SceneGeometry` (body, garment with its
  material and optional normal map, optional fibres; world metres) and a :class:`pgc.types.Light` into an
  opaque scene object of the implementation, and a map from its shape ids to segmentation labels
  (``pgc.synth.render.LABEL_BODY`` / ``LABEL_GARMENT``). ``geometry`` None is the empty scene: the light only.
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
  (:func:`pgc.synth.render.layers_from_samples` turns per-sample hits into these layers).
- :attr:`SceneRenderer.light_kinds` names the kinds of :class:`pgc.types.Light` it renders: ``"constant"``
  (radiance only) always; ``"envmap"`` (a latitude-longitude map turned ``rotation_deg`` about +Y) when it
  declares it. ``pgc eval`` refuses to render ground truth under a kind that is not declared.
- Every output is finite; outputs of one implementation are deterministic for fixed inputs.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any

import numpy as np

from pgc.roles._base import RoleImplementation
from pgc.types import Camera, Light

if TYPE_CHECKING:
    from pgc.synth.render import SceneGeometry


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
