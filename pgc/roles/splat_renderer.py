"""Role ``splat_renderer``: differentiable rasterisation of 3D Gaussians and the mesh-embedded splat fit.

Rendering contract (the 3DGS rasteriser)
- Gaussians in world space (:class:`pgc.types.WorldGaussians`); camera in the OpenCV convention.
- EWA splatting: 3D covariance ``R S S^T R^T`` projected with the Jacobian of the perspective map at the
  Gaussian's centre, plus a 0.1 px^2 low-pass filter (the pixel's box) on the diagonal of the 2D covariance,
  and the opacity times the coverage ``sqrt(det(Sigma2D - 0.1 I) / det(Sigma2D))`` that keeps the Gaussian's
  image-plane mass (Mip-Splatting's 2D filter); Gaussians with camera depth below ``near`` (default 0.01 m) are
  culled; footprint radius ``ceil(3 sqrt(lambda_max))``.
- Colour from real SH up to degree 3 (3DGS constants and sign convention), viewing direction
  ``normalize(mean - camera_centre)``, colour = SH + 0.5 clamped at 0.
- Pixel centres at (x + 0.5, y + 0.5). Front-to-back compositing in increasing depth:
  ``alpha_i = min(0.99, opacity_i coverage_i exp(-0.5 d^T Sigma2D^-1 d))``, contributions with ``alpha_i < 1/255``
  skipped, stop once transmittance falls below 1e-4.
- Output :class:`RenderOutput`: ``color`` (H, W, 3) = sum of weighted colours + T_final * background,
  ``alpha`` (H, W) = 1 - T_final, ``depth`` (H, W) = sum of weighted camera depths / alpha (0 where alpha is 0).
- Never NaN/Inf: degenerate scales, zero quaternions and Gaussians behind the camera give finite output.
- Inputs are checked once per call, before any implementation runs (:func:`check_render_inputs`, applied to
  every subclass's ``render``): a NaN or Inf in means, quats, scales, opacities, SH or the background, or
  arrays of the wrong shape, raise :class:`pgc.errors.PGCDataError` naming the array and the count.

Fit contract: :meth:`SplatRenderer.fit` optimises mesh-embedded Gaussians (:class:`pgc.types.GaussianSet`)
on ``mesh`` against the capture with the paper's loss and schedule (:class:`FitSplatsSettings`), reporting
progress through ``reporter``, and returns a :class:`SplatFit`. Implementations run the one fit loop of
:func:`pgc.splats.fit.fit_splats` and supply its array steps (:class:`pgc.splats.fit.FitBackend`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from pydantic import Field

from pgc.checks import require_finite
from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.options import Options, count, seed_field
from pgc.roles._base import RoleImplementation
from pgc.types import Camera, Capture, GaussianSet, Mesh, WorldGaussians

MAX_STEPS = 1_000_000
"""Most optimiser steps of a fit (the paper's splat fit takes 30000)."""
MAX_GAUSSIANS = 10_000_000
"""Most Gaussians of a fit (3DGS scenes hold up to a few million)."""


@dataclass
class RenderOutput:
    color: np.ndarray
    """(H, W, 3) float32 linear RGB, composited over the background (black if none)."""
    alpha: np.ndarray
    """(H, W) float32 accumulated opacity."""
    depth: np.ndarray | None = None
    """(H, W) float32 expected camera depth of the visible splats (0 where alpha is 0)."""


class FitSplatsSettings(Options):
    """Settings of :meth:`SplatRenderer.fit` (the ``[stages.fit_splats]`` table); paper values noted."""

    iterations: int = count(3000, 1, MAX_STEPS, (
        "most Adam steps (paper: 30000); the schedules (position lr decay, SH degree, coarse phase) span this "
        "count, and the fit stops earlier once the held-out PSNR has converged (converge_db)"))
    converge_every: int = count(100, 1, MAX_STEPS, (
        "steps between held-out PSNR evaluations (the convergence test and the time-to-PSNR curve)"))
    converge_db: float = Field(0.05, ge=0.0, description=(
        "stop when the last converge_patience evaluations raised the best held-out PSNR by less than this (dB); "
        "0 = always run every iteration"))
    converge_patience: int = count(3, 1, 10_000, "evaluations without converge_db of gain before stopping")
    converge_after: float = Field(0.25, ge=0.0, le=1.0, description=(
        "fraction of iterations before which the fit never stops (the coarse phase and the first SH degrees)"))
    relocate_every: int = count(0, 0, MAX_STEPS, (
        "steps between relocations of dead Gaussians (opacity below relocate_opacity) onto live ones, sampled by "
        "opacity (3DGS-MCMC style: the count stays fixed, opacity is split so the composite is unchanged); "
        "0 = never"))
    relocate_opacity: float = Field(0.005, gt=0.0, lt=1.0, description="opacity under which a Gaussian is dead")
    relocate_until: float = Field(0.75, ge=0.0, le=1.0, description=(
        "fraction of iterations after which Gaussians are no longer relocated (they settle before selection)"))
    coarse_fraction: float = Field(0.5, ge=0.0, le=1.0, description=(
        "fraction of the fit trained on half-resolution images (4x fewer pixels per step), then full resolution"))
    gaussians_per_pixel: float = Field(1.5, gt=0.0, description=(
        "initial count = this x the mean foreground pixels per training view x 2 (front and back halves)"))
    min_gaussians: int = count(2000, 1, MAX_GAUSSIANS, "fewest Gaussians of the initial set")
    max_gaussians: int = count(400000, 1, MAX_GAUSSIANS, "most Gaussians of the initial set")
    lr_position: float = Field(0.5e-4, gt=0.0, description="local-position lr at the start (paper 0.5e-4)")
    lr_position_final: float = Field(1e-7, gt=0.0, description="position lr at the end, exponential decay (paper 1e-7)")
    lr_other: float = Field(0.005, gt=0.0, description=(
        "lr of the SH DC term, opacity, scale and rotation (paper 0.005); higher SH bands use lr / 20 (3DGS)"))
    lr_scale: float = Field(0.0, ge=0.0, description=(
        "multiplies every lr; 0 = auto: sqrt(30000 / iterations) clamped to [1, 10], so a short run moves about "
        "as far as the paper's 30000 steps"))
    lambda_l1: float = Field(0.8, ge=0.0, le=1.0, description="weight of L1 vs (1 - SSIM) (paper 0.8)")
    lambda_mask: float = Field(0.1, ge=0.0, description="mask loss weight (paper 0.1)")
    lambda_surface: float = Field(0.0, ge=0.0, description=(
        "weight of the surface term: the mean squared offset of each Gaussian's local position along its "
        "triangle's normal (in units of the triangle scale k), keeping the near field on the surface it "
        "moves with; 0 = off (the paper)"))
    adam_eps: float = Field(1e-15, gt=0.0, le=1e-4, description=(
        "Adam's epsilon (3DGS and the paper: 1e-15); a larger one damps the steps of gradients at rounding "
        "level, which 1e-15 turns into full learning-rate steps (docs/robustness.md)"))
    lambda_opacity: float = Field(0.0, ge=0.0, description=(
        "weight of the mean opacity (the L1 term of 3DGS-MCMC, 0.01 there): Gaussians the training images do not "
        "need fade out, and with relocate_every they are moved onto live ones; 0 = off (the paper)"))
    mask_band: float = Field(0.03, ge=0.0, description=(
        "contour band half-width as a fraction of the (cropped, see focus) image height (paper 0.03)"))
    focus: str = Field("garment", pattern="^(garment|all)$", description=(
        "'garment': train on each view cropped to the garment's box (plus focus_margin) and place Gaussians only "
        "on faces seen inside a crop, so the steps spend their pixels and Gaussians where the kept splats are; "
        "'all': whole images and the whole mesh"))
    init_color: str = Field("views", pattern="^(views|random)$", description=(
        "initial DC colour: 'views' = median of the training images that see the Gaussian (a head start for short "
        "CPU fits), 'random' = U(0.5, 0.7) as in 3DGS"))
    focus_margin: float = Field(0.06, ge=0.0, le=1.0, description="crop margin, fraction of the image height")
    max_sh_degree: int = count(3, 0, 3, "highest spherical-harmonics degree")
    sh_interval: int = count(500, 1, MAX_STEPS, (
        "steps between SH degree increases at the paper's 30000 steps; scaled to the fraction of the fit"))
    holdout_every: int = count(8, 2, 10_000, (
        "every k-th view is held out for PSNR and model choice (with at least 2k views; fewer: none)"))
    prune_weight: float = Field(0.5, ge=0.0, description=(
        "prune Gaussians whose summed compositing weight over all training views is below this (pixels)"))
    select_count: bool = Field(True, description=(
        "after fitting, keep the smallest top-contribution fraction whose held-out PSNR is within margin_db"))
    select_sh: bool = Field(True, description="keep the lowest SH degree whose held-out PSNR is within margin_db")
    margin_db: float = Field(0.05, ge=0.0)
    drop_backfacing: bool = Field(False, description=(
        "drop Gaussians of triangles that face away from every training camera (interior of the garment shell)"))
    keep: str = Field("garment", pattern="^(garment|all)$", description=(
        "'garment': return only Gaussians on garment-labelled faces (parent indices stay those of the full mesh)"))
    checkpoint_dir: str | None = Field(None, description="directory for resumable checkpoints (None: none)")
    checkpoint_every: int = count(200, 1, MAX_STEPS, "steps between checkpoints")
    log_every: int = count(25, 1, MAX_STEPS, "steps between progress events")
    seed: int = seed_field()


@dataclass
class SplatFit:
    """What a fit returns: the Gaussians, the names of the views held out of training (the render stage
    chooses its kernel on them), and figures (the same keys for every backend: see :mod:`pgc.splats.fit`)."""

    gaussians: GaussianSet
    heldout_views: list[str] = field(default_factory=list)
    figures: dict[str, Any] = field(default_factory=dict)


GAUSSIAN_FIELDS = (("means", (3,)), ("quats", (4,)), ("scales", (3,)), ("opacities", ()), ("sh", (None, 3)))
"""The arrays of :class:`WorldGaussians` and their trailing shapes (None: any length)."""


def check_render_inputs(gaussians: WorldGaussians, background: np.ndarray | None = None,
                        where: str = "splat_renderer") -> None:
    """Refuse Gaussians whose arrays are not (N, ...) of the role's shapes or hold NaN/Inf (one
    ``np.isfinite`` pass per array), and a non-finite background: a renderer would drop or smear them."""
    n = None
    for name, tail in GAUSSIAN_FIELDS:
        a = np.asarray(getattr(gaussians, name))
        ok = a.ndim == 1 + len(tail) and all(t is None or t == s for t, s in zip(tail, a.shape[1:]))
        if not ok or (n is not None and a.shape[0] != n):
            shape = ", ".join(["N", *("K" if t is None else str(t) for t in tail)])
            raise PGCDataError(f"{where}: WorldGaussians.{name} must have shape ({shape}) with N = {n or 'len(means)'}, "
                               f"got {a.shape}")
        n = a.shape[0]
        require_finite(where, f"WorldGaussians.{name}", a)
    if background is not None:
        require_finite(where, "background", background)


def _checked(render: Callable[..., RenderOutput]) -> Callable[..., RenderOutput]:
    """``render`` preceded by :func:`check_render_inputs` (at the public entry: the fits call their backends'
    steps, not ``render``)."""

    def checked(self: "SplatRenderer", gaussians: WorldGaussians, camera: Camera, background: np.ndarray | None = None,
                *args: Any, **kwargs: Any) -> RenderOutput:
        check_render_inputs(gaussians, background, f"splat_renderer {type(self).__name__}.render")
        return render(self, gaussians, camera, background, *args, **kwargs)

    return checked


class SplatRenderer(RoleImplementation, ABC):
    role = "splat_renderer"
    input_checks = {"render": _checked}
    """Every implementation's ``render`` checks its inputs first (:func:`check_render_inputs`)."""

    @abstractmethod
    def render(self, gaussians: WorldGaussians, camera: Camera, background: np.ndarray | None = None,
               sh_degree: int | None = None) -> RenderOutput:
        """Render world Gaussians from ``camera``. ``background``: (H, W, 3) or (3,) linear RGB."""

    @abstractmethod
    def fit(self, capture: Capture, mesh: Mesh, settings: FitSplatsSettings | None = None,
            reporter: Reporter | None = None) -> SplatFit:
        """Fit mesh-embedded Gaussians on ``mesh`` (the full labelled body mesh) to ``capture``."""
