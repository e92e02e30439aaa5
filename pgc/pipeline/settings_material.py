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
    views_per_step: int = Field(12, ge=1)
    """Each Adam step renders one film of at most this many views (same image size, side by side); the steps
    cycle through the films. Bounds the cost of a step whatever the view count (the default scene's 32 views:
    3 films). Fewer views per step add gradient noise from the view sampling: with 9 views in 2 films, the
    Disney sheen wandered to 0.06-0.18 on the knit (0.03-0.07 dB held out) instead of staying near 0."""
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
    """Model selection: the simplest model whose held-out PSNR is within this of the best is chosen. 0.3 dB:
    equally adequate models differ by up to ~0.1 dB held out (seeds, Monte Carlo noise, a richer model
    absorbing scene mismatch: measured 0.01-0.10 dB on the synthetic Lambertian control and knit), so
    smaller gains are no evidence of sheen."""
    eval_spp: int = Field(1024, ge=1)
    """Samples per pixel of the renders that measure held-out PSNR. At 64 spp the renders' own Monte Carlo
    noise is ~90 % of the held-out error of a good fit, and richer BRDFs sample noisier, which hid the knit's
    sheen (docs/pbr.md); 1024 spp costs ~15 s per selection against ~6 min of fitting (192 px)."""
    select_model: bool = False
    """Fit lambertian, disney and pgc-sheen and keep the simplest adequate one (pgc.brdfs.select)."""
    seed: int = 0


SETTINGS = {"material": MaterialFitSettings}
