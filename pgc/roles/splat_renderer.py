"""Role ``splat_renderer``: differentiable rasterisation of 3D Gaussians and the mesh-embedded splat fit.

Rendering contract (the 3DGS rasteriser, METHOD.md section 2)
- Gaussians in world space (:class:`pgc.types.WorldGaussians`); camera in the OpenCV convention.
- EWA splatting: 3D covariance ``R S S^T R^T`` projected with the Jacobian of the perspective map at the
  Gaussian's centre, plus a 0.3 px^2 low-pass dilation on the diagonal of the 2D covariance; Gaussians with
  camera depth below ``near`` (default 0.01 m) are culled; footprint radius ``ceil(3 sqrt(lambda_max))``.
- Colour from real SH up to degree 3 (3DGS constants and sign convention), viewing direction
  ``normalize(mean - camera_centre)``, colour = SH + 0.5 clamped at 0.
- Pixel centres at (x + 0.5, y + 0.5). Front-to-back compositing in increasing depth:
  ``alpha_i = min(0.99, opacity_i exp(-0.5 d^T Sigma2D^-1 d))``, contributions with ``alpha_i < 1/255``
  skipped, stop once transmittance falls below 1e-4.
- Output :class:`RenderOutput`: ``color`` (H, W, 3) = sum of weighted colours + T_final * background,
  ``alpha`` (H, W) = 1 - T_final, ``depth`` (H, W) = sum of weighted camera depths / alpha (0 where alpha is 0).
- Never NaN/Inf: degenerate scales, zero quaternions and Gaussians behind the camera give finite output.

Fit contract: :meth:`SplatRenderer.fit` optimises mesh-embedded Gaussians (:class:`pgc.types.GaussianSet`)
on ``mesh`` against the capture with the paper's loss and schedule, reporting progress through ``reporter``,
and returns them with per-stage figures.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pgc.events import Reporter
from pgc.roles._base import RoleImplementation
from pgc.types import Camera, Capture, GaussianSet, Mesh, WorldGaussians


@dataclass
class RenderOutput:
    color: np.ndarray
    """(H, W, 3) float32 linear RGB, composited over the background (black if none)."""
    alpha: np.ndarray
    """(H, W) float32 accumulated opacity."""
    depth: np.ndarray | None = None
    """(H, W) float32 expected camera depth of the visible splats (0 where alpha is 0)."""


@dataclass
class SplatFit:
    gaussians: GaussianSet
    figures: dict[str, Any] = field(default_factory=dict)


class SplatRenderer(RoleImplementation, ABC):
    role = "splat_renderer"

    @abstractmethod
    def render(self, gaussians: WorldGaussians, camera: Camera, background: np.ndarray | None = None,
               sh_degree: int | None = None) -> RenderOutput:
        """Render world Gaussians from ``camera``. ``background``: (H, W, 3) or (3,) linear RGB."""

    @abstractmethod
    def fit(self, capture: Capture, mesh: Mesh, settings: Any = None,
            reporter: Reporter | None = None) -> SplatFit:
        """Fit mesh-embedded Gaussians on ``mesh`` to ``capture`` (settings: the stage's options)."""
