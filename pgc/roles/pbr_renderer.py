"""Role ``pbr_renderer``: shades a mesh with a BRDF and lighting, in screen or texture space; fits materials.

Contract
- :meth:`render`: the mesh seen from ``camera`` -> :class:`pgc.roles.splat_renderer.RenderOutput`
  (linear RGB radiance over a black background, alpha = pixel coverage). ``occluder`` (e.g. the body)
  shadows the mesh and hides it where it is in front; it is not itself returned (zero colour and alpha).
- :meth:`render_texture`: outgoing radiance toward ``camera``'s centre at every texel centre of the mesh's
  UV atlas, (H, W, 3), plus the (H, W) coverage of the atlas (0 outside charts). Shadowing and indirect
  light are included where the implementation supports them (documented per implementation);
  ``occluder`` (e.g. the body under a garment) casts shadows on the mesh but is not itself returned.
- :meth:`fit`: fits the parameters of ``brdf`` (not the base-colour texture) and the RGB radiance of the
  light to ``capture`` on ``mesh``; returns the fitted material, light and figures. The light's shape is the
  capture's recorded light (an environment map and its rotation, or a constant) or, where the capture records
  none, a constant environment (:func:`pgc.brdfs.fitdata.fit_light`, ``MaterialFitSettings.light``); the
  returned light has that shape and the fitted radiance.
- Inputs are checked before any implementation's :meth:`render` or :meth:`render_texture` runs
  (:func:`check_shading_inputs`): a NaN or Inf in ``material.base_color``, ``material.params``,
  ``light.radiance``, ``light.envmap`` or ``light.rotation_deg`` raises :class:`pgc.errors.PGCDataError` naming
  the array and the count, instead of an image of NaN.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Callable, Literal

import numpy as np
from pydantic import Field

from pgc.checks import require_finite
from pgc.events import Reporter
from pgc.options import Options, count, seed_field
from pgc.roles._base import RoleImplementation
from pgc.roles.splat_renderer import RenderOutput
from pgc.types import Camera, Capture, Light, Material, Mesh

MAX_SPP = 65536
"""Most samples per pixel of a render."""
MAX_STEPS = 1_000_000
"""Most optimiser steps of a fit."""


class MaterialFitSettings(Options):
    """Settings of :meth:`PBRRenderer.fit` (the ``[stages.material]`` table): BRDF parameters and the light's
    radiance fitted by differentiable rendering (paper: Adam, lr 0.01, 4 spp, 3000 iterations; here stopped
    when the loss stops improving)."""

    light: Literal["auto", "capture", "constant"] = "auto"
    """The light the fit renders under (its RGB radiance is fitted): 'capture', the capture's recorded light
    (environment map and rotation; refused when the capture records none); 'constant', a constant environment
    whatever the capture records (the paper's assumption); 'auto', the capture's light where it records one,
    else a constant."""

    lr: float = Field(0.01, gt=0.0)
    """Adam learning rate (paper: 0.01). Scalars and colours are optimised directly; the light radiance
    as its logarithm (a step changes it by ~lr relative, whatever its scale)."""
    spp: int = count(4, 1, MAX_SPP)
    """Samples per pixel of each differentiable render (paper: 4)."""
    views_per_step: int = count(12, 1, 10_000)
    """Each Adam step renders one film of at most this many views (same image size, side by side); the steps
    cycle through the films. Bounds the cost of a step whatever the view count; fewer views per step add
    gradient noise from the view sampling."""
    shards: int = count(2, 1, 256)
    """Each film's views are dealt into this many shards, rendered on one Dr.Jit thread each (in parallel
    processes, up to the cores the process is allotted) and their gradients summed in shard order: the result
    does not depend on the thread count (Dr.Jit's multi-threaded gradient sums do, by racy atomic adds)."""
    parallel_min_pixels: int = count(16384, 0, 2**31 - 1)
    """Shards render in parallel processes only when a film has at least this many pixels: starting a worker
    process costs more than a small film's steps save (docs/pbr.md). The result is the same bytes either way."""
    max_depth: int = count(4, 2, 64)
    """Path length while fitting and when comparing models (4: direct light plus two indirect bounces;
    light trapped between garment and body needs them)."""
    max_iterations: int = count(3000, 1, MAX_STEPS)
    """Upper bound on Adam steps (paper: 3000 fixed)."""
    patience: int = count(100, 1, 100_000)
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
    polish: bool = False
    """After Adam, a Levenberg-Marquardt polish of the same variables (parameters scaled to [0, 1] by their
    bounds, log radiance) on the weighted residuals of every film, rendered twice at ``polish_spp`` with two
    fixed seeds (a deterministic problem; its cost, the product of the two residuals, has no render variance in
    its expectation), the Jacobians by forward differences. Adam's 4-spp steps stop on the slope of the
    loss's flat valleys (roughness against sheen colour); the polish walks further along them. Cost per
    iteration: 2 x (variables + 1) renders of every film at ``polish_spp`` (pgc-sheen: 18), plus 2 per
    rejected trial: 70-170 s on the 12-view 48 px in-family controls, 1.7-4.5x Adam's seconds. On the five
    controls (seed 0, uniform light) it took the roughness from 15-72 % off to 3-21 % and the sheen colour from
    33-69 % to 2-45 % (on the knit, what remains is its weave's mismatch; docs/pbr.md, "The polish"). Off by
    default: its cost grows with every film's pixels, about 40x the controls' on the default demo's 128 views of
    96 px (an hour or more), where Adam takes under a minute."""
    polish_spp: int = count(64, 1, MAX_SPP)
    """Samples per pixel of the polish's renders (low-discrepancy sampler). Their noise, not the optimiser,
    bounds where the polish ends along a weakly determined direction."""
    polish_iterations: int = count(10, 1, 1000)
    """Most Jacobians of the polish."""
    polish_tolerance: float = Field(1e-3, gt=0.0)
    """The polish has converged when the step at its initial damping moves no variable more than this (0.1 % of
    a parameter's range, 0.1 % relative in the radiance; :func:`pgc.least_squares.levenberg_marquardt`)."""
    max_image_side: int = count(96, 8, 16384)
    """Images are area-downsampled so their longer side is at most this (fit cost ~ pixels)."""
    holdout_every: int = count(4, 2, 10_000)
    """Model selection: every k-th view is held out of fitting and used to compare the models."""
    margin_db: float = Field(0.3, ge=0.0)
    """Model selection: the simplest model whose held-out PSNR is within this of the best is chosen (equally
    adequate models differ by up to about 0.1 dB held out; docs/pbr.md has the measurements)."""
    eval_spp: int = count(1024, 1, MAX_SPP)
    """Samples per pixel of the renders that measure held-out PSNR: high enough that the renders' own Monte
    Carlo noise does not decide the model selection (docs/pbr.md, "Model selection")."""
    select_model: bool = False
    """Fit lambertian, disney and pgc-sheen and keep the simplest adequate one (pgc.brdfs.select)."""
    seed: int = seed_field()


@dataclass
class MaterialFit:
    material: Material
    light: Light
    figures: dict[str, Any] = field(default_factory=dict)


def check_shading_inputs(material: Material, light: Light, where: str = "pbr_renderer") -> None:
    """Refuse a material or light holding NaN/Inf (one ``np.isfinite`` pass per array): a renderer would
    return an image of NaN for them."""
    fix = "give finite values (a texture or map read from a file: check the file)"
    if material.base_color is not None:
        require_finite(where, "material.base_color", material.base_color, fix)
    for key, value in material.params.items():
        require_finite(where, f"material.params['{key}']", value)
    require_finite(where, "light.radiance", light.radiance)
    if light.envmap is not None:
        require_finite(where, "light.envmap", light.envmap, fix)
    require_finite(where, "light.rotation_deg", float(light.rotation_deg))


def _checked(method: Callable[..., Any]) -> Callable[..., Any]:
    """``method`` (``render`` or ``render_texture``) preceded by :func:`check_shading_inputs`."""

    def checked(self: "PBRRenderer", mesh: Mesh, material: Material, light: Light, *args: Any,
                **kwargs: Any) -> Any:
        check_shading_inputs(material, light, f"pbr_renderer {type(self).__name__}.{method.__name__}")
        return method(self, mesh, material, light, *args, **kwargs)

    return checked


class PBRRenderer(RoleImplementation, ABC):
    role = "pbr_renderer"
    input_checks = {"render": _checked, "render_texture": _checked}
    """Every implementation's ``render`` and ``render_texture`` check the material and light first."""

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
