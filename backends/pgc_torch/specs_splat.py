"""Registration of the torch splat renderer (light: pgc core and pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import MAX_THREADS, Options, count
from pgc.registry import ImplementationSpec


class TorchSplatOptions(Options):
    compositor: Literal["auto", "fused", "torch"] = Field(
        "auto", description="rendering path: 'fused' (projection, SH, binning, compositing and their backward in "
                            "one compiled SIMD/OpenMP kernel, built once and cached), 'torch' (pure torch: needs no "
                            "compiler, slow; the cross-check), 'auto' (fused if it builds, else torch)")
    tile_size: int = Field(16, ge=4, le=64, description="tile edge in pixels for binning")
    threads: int = count(0, 0, MAX_THREADS, "kernel threads; 0 = the cores allotted to the process (OMP_NUM_THREADS, "
                         "else all usable cores)")
    near: float = Field(0.01, gt=0.0, description="near plane (metres): Gaussians with camera z below are culled")


SPECS = [ImplementationSpec(
    role="splat_renderer", name="torch", factory="pgc_torch.splat.renderer:TorchSplatRenderer",
    description="EWA Gaussian splatting in torch on the fused compiled kernel (pure-torch fallback); "
                "mesh-embedded fit",
    options="pgc_torch.specs_splat:TorchSplatOptions", requires=("torch",), extra="torch")]
