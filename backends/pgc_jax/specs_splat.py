"""Registration of the JAX ``splat_renderer`` (light: pgc core and pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import MAX_THREADS, Options, count
from pgc.registry import ImplementationSpec


class JaxSplatOptions(Options):
    compositor: Literal["auto", "fused", "xla"] = Field(
        "auto", description="rendering path: 'xla' (projection and dense tile-chunk compositing traced and compiled "
                            "by XLA; runs wherever JAX does), 'fused' (the project's compiled CPU kernel called "
                            "from the traced program, with its analytic backward as the VJP), 'auto' (fused on a "
                            "CPU backend when the kernel builds, else xla)")
    threads: int = count(0, 0, MAX_THREADS, "fused kernel threads; 0 = the cores allotted to the process "
                                            "(OMP_NUM_THREADS, else all usable cores)")
    tile_size: int = Field(8, ge=4, le=64, description=(
        "xla compositor: tile edge in pixels; a tile's pixels are one block (8 was fastest in bench_splat_jax.py)"))
    chunk_size: int = Field(16, ge=4, le=1024, description=(
        "xla compositor: Gaussians per depth-sorted chunk of a tile list, the other block side (16 was fastest)"))
    near: float = Field(0.01, gt=0.0, description="near plane (metres): Gaussians with camera depth below are culled")
    precision: str = Field("float32", pattern="^(float32|float64)$",
                           description="float dtype of rendering and fitting (float64 needs jax_enable_x64)")


SPECS = [
    ImplementationSpec(
        role="splat_renderer", name="jax", factory="pgc_jax.splat.renderer:JaxSplatRenderer",
        description="3DGS rasteriser in JAX: the compiled fused kernel as a custom VJP on CPU, or tile chunks "
                    "composited densely by XLA; jit + grad; mesh-embedded fit",
        options="pgc_jax.specs_splat:JaxSplatOptions", requires=("jax",), extra="jax"),
]
