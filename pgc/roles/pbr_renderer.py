"""Role ``pbr_renderer``: shades a mesh with a BRDF and lighting, in screen or texture space; fits materials.

Contract
- :meth:`render`: the mesh seen from ``camera`` -> :class:`pgc.roles.splat_renderer.RenderOutput`
  (linear RGB radiance over a black background, alpha = pixel coverage). ``occluder`` (e.g. the body)
  shadows the mesh and hides it where it is in front; it is not itself returned (zero colour and alpha).
- :meth:`render_texture`: outgoing radiance toward ``camera``'s centre at every texel centre of the mesh's
  UV atlas, (H, W, 3), plus the (H, W) coverage of the atlas (0 outside charts). Shadowing and indirect
  light are included where the implementation supports them (documented per implementation);
  ``occluder`` (e.g. the body under a garment) casts shadows on the mesh but is not itself returned.
- :meth:`fit`: fits the parameters of ``brdf`` (not the base-colour texture) and the RGB radiance of a
  constant environment light to ``capture`` on ``mesh``; returns the fitted material, light and figures.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydantic import Field

from pgc.events import Reporter
from pgc.options import Options
from pgc.roles._base import RoleImplementation
from pgc.roles.splat_renderer import RenderOutput
from pgc.types import Camera, Capture, Light, Material, Mesh


class MaterialFitSettings(Options):
    """Settings of :meth:`PBRRenderer.fit` (the ``[stages.material]`` table): BRDF parameters and the constant
    light fitted by differentiable rendering (paper: Adam, lr 0.01, 4 spp, 3000 iterations; here stopped when
    the loss stops improving)."""

    lr: float = Field(0.01, gt=0.0)
    """Adam learning rate (paper: 0.01). Scalars and colours are optimised directly; the light radiance
    as its logarithm (a step changes it by ~lr relative, whatever its scale)."""
    spp: int = Field(4, ge=1)
    """Samples per pixel of each differentiable render (paper: 4)."""
    views_per_step: int = Field(12, ge=1)
    """Each Adam step renders one film of at most this many views (same image size, side by side); the steps
    cycle through the films. Bounds the cost of a step whatever the view count; fewer views per step add
    gradient noise from the view sampling."""
    shards: int = Field(2, ge=1)
    """Each film's views are dealt into this many shards, rendered on one Dr.Jit thread each (in parallel
    processes, up to the cores the process is allotted) and their gradients summed in shard order: the result
    does not depend on the thread count (Dr.Jit's multi-threaded gradient sums do, by racy atomic adds)."""
    parallel_min_pixels: int = Field(16384, ge=0)
    """Shards render in parallel processes only when a film has at least this many pixels: a worker process
    takes about half a second to start, more than a small fit saves (the tiny demo's 48 px films take 40 steps
    of a few milliseconds). The result is the same bytes either way."""
    max_depth: int = Field(4, ge=2)
    """Path length while fitting and when comparing models (4: direct light plus two indirect bounces;
    light trapped between garment and body needs them)."""
    max_iterations: int = Field(3000, ge=1)
    """Upper bound on Adam steps (paper: 3000 fixed)."""
    patience: int = Field(100, ge=1)
    """Stopping window W: stop when the mean loss of the last W steps is not ``min_improvement`` (relative)
    below the mean of the W steps before (the 4-spp loss is noisy; window means see through it)."""
    min_improvement: float = Field(2e-3, ge=0.0)
    max_drift: float = Field(0.1, gt=0.0)
    """Stop only when, besides the loss plateau, no optimised variable (parameters scaled to [0, 1] by their
    bounds, log radiance) moved more than this fraction of ``lr x patience`` net over the last window
    (noise-driven Adam steps mostly cancel; a parameter still on its way moves ~lr per step)."""
    final_lr_factor: float = Field(0.1, gt=0.0, le=1.0)
    """Once stopping is decided, ``patience`` more steps run at this fraction of ``lr``; the result is the mean
    of their iterates (smaller noise-driven jitter; at a bound the jitter is one-sided and biases a mean)."""
    max_image_side: int = Field(96, ge=8)
    """Images are area-downsampled so their longer side is at most this (fit cost ~ pixels)."""
    holdout_every: int = Field(4, ge=2)
    """Model selection: every k-th view is held out of fitting and used to compare the models."""
    margin_db: float = Field(0.3, ge=0.0)
    """Model selection: the simplest model whose held-out PSNR is within this of the best is chosen (equally
    adequate models differ by up to about 0.1 dB held out; docs/pbr.md has the measurements)."""
    eval_spp: int = Field(1024, ge=1)
    """Samples per pixel of the renders that measure held-out PSNR: high enough that the renders' own Monte
    Carlo noise does not decide the model selection (docs/pbr.md, "Model selection")."""
    select_model: bool = False
    """Fit lambertian, disney and pgc-sheen and keep the simplest adequate one (pgc.brdfs.select)."""
    seed: int = 0


@dataclass
class MaterialFit:
    material: Material
    light: Light
    figures: dict[str, Any] = field(default_factory=dict)


class PBRRenderer(RoleImplementation, ABC):
    role = "pbr_renderer"

    @abstractmethod
    def render(self, mesh: Mesh, material: Material, light: Light, camera: Camera,
               occluder: Mesh | None = None) -> RenderOutput:
        """Render ``mesh`` with ``material`` under ``light`` from ``camera`` (``occluder``: see the contract)."""

    @abstractmethod
    def render_texture(self, mesh: Mesh, material: Material, light: Light, camera: Camera,
                       resolution: tuple[int, int], occluder: Mesh | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Radiance toward ``camera`` at each texel of the UV atlas: ((H, W, 3), (H, W) coverage)."""

    def fit(self, capture: Capture, mesh: Mesh, material: Material, settings: MaterialFitSettings | None = None,
            reporter: Reporter | None = None) -> MaterialFit:
        """Fit ``material``'s BRDF parameters and the light to ``capture``. Optional for a renderer."""
        from pgc.errors import PGCPluginError

        raise PGCPluginError(f"pbr_renderer '{type(self).__name__}' cannot fit materials; use one that can "
                             "(e.g. 'mitsuba')")
