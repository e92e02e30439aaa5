"""Options of the ``fit_splats`` stage (METHOD.md section 2; paper values noted)."""

from __future__ import annotations

from pydantic import Field

from pgc.options import Options


class FitSplatsSettings(Options):
    iterations: int = Field(0, ge=0, description=(
        "Adam steps (paper: 30000); 0 = auto: run for time_budget_s, the schedules (position lr decay, SH degree, "
        "coarse phase) following the elapsed fraction of the budget"))
    max_iterations: int = Field(30000, ge=1)
    time_budget_s: float = Field(420.0, gt=0.0, description="wall-clock budget of the optimisation loop (auto mode)")
    coarse_fraction: float = Field(0.5, ge=0.0, le=1.0, description=(
        "fraction of the fit trained on half-resolution images (4x fewer pixels per step), then full resolution"))
    gaussians_per_pixel: float = Field(1.5, gt=0.0, description=(
        "initial count = this x the mean foreground pixels per training view x 2 (front and back halves)"))
    min_gaussians: int = Field(2000, ge=1)
    max_gaussians: int = Field(400000, ge=1)
    lr_position: float = Field(0.5e-4, gt=0.0, description="local-position lr at the start (paper 0.5e-4)")
    lr_position_final: float = Field(1e-7, gt=0.0, description="position lr at the end, exponential decay (paper 1e-7)")
    lr_other: float = Field(0.005, gt=0.0, description=(
        "lr of the SH DC term, opacity, scale and rotation (paper 0.005); higher SH bands use lr / 20 (3DGS)"))
    lr_scale: float = Field(0.0, ge=0.0, description=(
        "multiplies every lr; 0 = auto: sqrt(30000 / steps) clamped to [1, 10] (steps: the set count, or in auto "
        "mode the count the budget allows, measured on the first steps), so a short run moves about as far "
        "as the paper's 30000 steps"))
    lambda_l1: float = Field(0.8, ge=0.0, le=1.0, description="weight of L1 vs (1 - SSIM) (paper 0.8)")
    lambda_mask: float = Field(0.1, ge=0.0, description="mask loss weight (paper 0.1)")
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
    max_sh_degree: int = Field(3, ge=0, le=3)
    sh_interval: int = Field(500, ge=1, description=(
        "steps between SH degree increases at the paper's 30000 steps; scaled to the fraction of the fit"))
    holdout_every: int = Field(8, ge=2, description="every k-th view is held out for PSNR and model choice")
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
    checkpoint_every: int = Field(200, ge=1)
    log_every: int = Field(25, ge=1)
    seed: int = 0


SETTINGS = {"fit_splats": FitSplatsSettings}
