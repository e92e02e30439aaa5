"""Stage ``render``: the hybrid of the PBR far field and the Gaussian near field on the run's frames, with the
3DGS-only and PBR-only ablations (:mod:`pgc.pipeline.render`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pydantic import Field

from pgc.errors import PGCConfigError
from pgc.filtering.auto import KernelSelection
from pgc.options import Options, count
from pgc.stages.declaration import Stage

if TYPE_CHECKING:
    from pgc.config import RoleChoice


class RenderSettings(Options):
    kernel: KernelSelection = KernelSelection(mode="metric")
    """How the low-pass kernel is set: by default the smallest size whose hybrid's LPIPS on the views the splat
    fit held out, at the capture pose, is within 10 % of the score range from the best (mode 'error' is the
    paper's rule; docs/pipeline.md compares them). Without the LPIPS plugin among the run's metrics the default
    falls back to mode 'error'."""
    views: int = count(4, 1, 10_000, "capture cameras used for novel frames (evenly spread)")
    frame_stride: int = count(10, 1, 100_000, "render every n-th simulated frame")
    texture_size: int = count(256, 16, 4096, "far-field texture T_t resolution (texels)")
    kernel_views: int = count(4, 1, 10_000, (
        "capture views the kernel (and an auto far field) is chosen on: those the splat fit held out, if recorded"))
    far_source: str = Field("mesh", pattern="^(auto|splats|mesh)$", description=(
        "the far field S_t: 'splats' = the Gaussians coloured by the texture-space PBR radiance (the paper), "
        "'mesh' = the PBR renderer's image of the mesh (no texture-space pass), 'auto' = the one whose hybrid "
        "scores better on the kernel views (with the kernel each source chooses there)"))
    far_lookup: str = Field("visible", pattern="^(visible|parent)$", description=(
        "where a Gaussian reads the far-field texture: 'parent' = its parent triangle (the paper), 'visible' = "
        "the garment surface seen through its centre (see pgc.pipeline.compose)"))
    silhouette: str = Field("far", pattern="^(near|far)$", description=(
        "whose alpha shapes the hybrid: 'near' = the Gaussians' (the paper; with far_source 'splats' both agree), "
        "'far' = the far field's, the simulated mesh's own coverage when the far field is the mesh, with h(G) "
        "weighted by the Gaussians' alpha"))
    outline_fade: float = Field(1.0, ge=0.0, le=10.0, description=(
        "with silhouette 'far': the hybrid blends linearly into the far field over this many kernel widths "
        "inside the far field's outline (0: off, the paper's l(S) + h(G) up to the edge)"))
    body_occludes: bool = Field(True, description="the body hides the garment layers where it is in front")
    detail: str = Field("multiplicative", pattern="^(additive|multiplicative|ratio|residual)$", description=(
        "how the near field's detail enters the hybrid: 'additive' = l(S) + h(G) (the paper; the detail keeps its "
        "capture-light amplitude under any light), 'multiplicative' = l(S) G / l(G) (the detail scales with the far "
        "field's shading, so it follows a novel light), 'ratio' = l(S) + h(G) l(S) / l(S_c) with S_c the far field "
        "under the capture light (additive under the capture light; under another light a second far-field render "
        "per frame), 'residual' = S + l(S) (h(G) / l(G) - h(S_c) / l(S_c)): the whole far field, its own high band "
        "relit, plus the near field's relative detail beyond the far field's under the capture light "
        "(multiplicative under the capture light; the same second render); the ratios are guarded where their "
        "denominator is near 0"))


def metric_role(settings: RenderSettings) -> dict[str, str]:
    """The kernel rule's mode 'metric' scores with one of the run's metrics: that metric (its options and
    version), not the run's list of metrics, then decides the render."""
    return {"metric": settings.kernel.metric} if settings.kernel.mode == "metric" else {}


def check_kernel_metric(settings: RenderSettings, given: dict[str, Any], roles: dict[str, RoleChoice],
                        source: str) -> RenderSettings:
    """The kernel rule's mode 'metric' needs its metric among the run's. Asked for in the config, a missing one
    is an error; as the default, the rule falls back to mode 'error' (an installation without the LPIPS
    plugin still runs)."""
    kernel = settings.kernel
    metrics = [i.name for i in roles["metric"].implementations] if "metric" in roles else []
    if kernel.mode != "metric" or kernel.metric in metrics:
        return settings
    asked = given.get("kernel") or {}
    if "mode" in asked or "metric" in asked:
        raise PGCConfigError(f"{source}: [stages.render.kernel] metric = '{kernel.metric}' is not among the run's "
                             f"metrics {metrics}; name one of them, or add it to [metric] use (and install its "
                             "plugin)")
    return settings.model_copy(update={"kernel": kernel.model_copy(update={"mode": "error"})})


STAGE = Stage(name="render", command="render", version="4", inputs=("run", "asset", "light"),
              outputs=("frame_*.npz", "render.json"), folder="RUN/render",
              roles=("splat_renderer", "pbr_renderer", "filter"), settings=RenderSettings, settings_roles=metric_role,
              check=check_kernel_metric, events=("choose_kernel", "render_frames"))
