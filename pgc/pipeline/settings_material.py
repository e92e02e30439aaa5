"""Options of the material stage: BRDF parameters and the constant light fitted by differentiable rendering
(paper: Adam, lr 0.01, 4 spp, path integrator, 3000 iterations; here stopped when the loss stops improving)."""

from pydantic import Field

from pgc.options import Options


class MaterialFitSettings(Options):
    lr: float = Field(0.01, gt=0.0)
    """Adam learning rate (paper: 0.01). Scalars and colours are optimised directly; the light radiance
    as its logarithm (a step changes it by ~lr relative, whatever its scale)."""
    spp: int = Field(4, ge=1)
    """Samples per pixel of each differentiable render (paper: 4)."""
    max_depth: int = Field(4, ge=2)
    """Path length while fitting and when comparing models (4: direct light plus two indirect bounces;
    light trapped between garment and body needs them)."""
    max_iterations: int = Field(3000, ge=1)
    """Upper bound on Adam steps (paper: 3000 fixed)."""
    patience: int = Field(100, ge=1)
    """Stopping window W: stop when the mean loss of the last W steps is not ``min_improvement`` (relative)
    below the mean of the W steps before (the 4-spp loss is noisy; window means see through it)."""
    min_improvement: float = Field(2e-3, ge=0.0)
    max_image_side: int = Field(96, ge=8)
    """Images are area-downsampled so their longer side is at most this (fit cost ~ pixels)."""
    holdout_every: int = Field(4, ge=2)
    """Model selection: every k-th view is held out of fitting and used to compare the models."""
    margin_db: float = Field(0.3, ge=0.0)
    """Model selection: the simplest model whose held-out PSNR is within this of the best is chosen. 0.3 dB:
    on the synthetic Lambertian control a 5-parameter sheen model still gains 0.2 dB held out (it absorbs
    model/scene mismatch: occluder colour, noise), so smaller gains are no evidence of sheen."""
    eval_spp: int = Field(64, ge=1)
    """Samples per pixel of the renders that measure held-out PSNR."""
    select_model: bool = False
    """Fit lambertian, disney and pgc-sheen and keep the simplest adequate one (pgc.brdfs.select)."""
    seed: int = 0


SETTINGS = {"material": MaterialFitSettings}
