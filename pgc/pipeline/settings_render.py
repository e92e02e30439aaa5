"""Options of the ``render`` stage (the hybrid of the PBR far field and the Gaussian near field)."""

from pydantic import Field

from pgc.filtering.auto import KernelSelection
from pgc.options import Options, count


class RenderSettings(Options):
    kernel: KernelSelection = KernelSelection(mode="metric")
    """How the low-pass kernel is set: by default the smallest size whose hybrid's LPIPS on the views the splat
    fit held out, at the capture pose, is within 10 % of the score range from the best (mode 'error' is the
    paper's rule). On the knit scene it picks 11 px (novel-pose LPIPS 0.183 against 0.193 for the error rule's
    5 px), on the default scene 7 px, on the cotton scene 5 px (docs/pipeline.md). Without the LPIPS plugin
    among the run's metrics the default falls back to mode 'error'."""
    views: int = count(4, 1, 10_000, "capture cameras used for novel frames (evenly spread)")
    frame_stride: int = count(10, 1, 100_000, "render every n-th simulated frame")
    texture_size: int = count(256, 16, 4096, "far-field texture T_t resolution (texels)")
    kernel_views: int = count(4, 1, 10_000, (
        "capture views the kernel (and an auto far field) is chosen on: those the splat fit held out, if recorded"))
    far_source: str = Field("mesh", pattern="^(auto|splats|mesh)$", description=(
        "the far field S_t: 'splats' = the Gaussians coloured by the texture-space PBR radiance (the paper), "
        "'mesh' = the PBR renderer's image of the mesh (no texture-space pass), 'auto' = the one whose hybrid "
        "scores better on the kernel views (with the kernel each source chooses there). Default 'mesh': "
        "the kernel views are at the capture pose, where the splats' far field scores well (LPIPS 0.049 "
        "against 0.055 on the knit) but it does not follow new poses (0.265 against 0.186 on goalpost)"))
    far_lookup: str = Field("visible", pattern="^(visible|parent)$", description=(
        "where a Gaussian reads the far-field texture: 'parent' = its parent triangle (the paper), 'visible' = "
        "the garment surface seen through its centre (see pgc.pipeline.compose)"))
    silhouette: str = Field("far", pattern="^(near|far)$", description=(
        "whose alpha shapes the hybrid: 'near' = the Gaussians' (the paper; with far_source 'splats' both agree), "
        "'far' = the far field's, the simulated mesh's own coverage when the far field is the mesh, with h(G) "
        "weighted by the Gaussians' alpha"))
    outline_fade: float = Field(1.0, ge=0.0, le=10.0, description=(
        "with silhouette 'far': the hybrid blends linearly into the far field over this many kernel widths "
        "inside the far field's outline (0: off, the paper's l(S) + h(G) up to the edge). At 1 (the default) "
        "novel-pose FSIM rises by 0.003-0.009 and PSNR by 0.1-0.4 dB, LPIPS equal or better, on two scenes "
        "and two seeds each (docs/pipeline.md)"))
    body_occludes: bool = Field(True, description="the body hides the garment layers where it is in front")

