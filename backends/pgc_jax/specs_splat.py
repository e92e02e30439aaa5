"""Registration of the JAX ``splat_renderer`` (light: pgc core and pydantic only)."""

from __future__ import annotations

from pydantic import Field

from pgc.options import Options
from pgc.registry import ImplementationSpec


class JaxSplatOptions(Options):
    tile_size: int = Field(8, ge=4, le=64, description=(
        "tile edge in pixels; a tile's pixels are one block (8 was fastest in bench_splat_jax.py)"))
    chunk_size: int = Field(16, ge=4, le=1024, description=(
        "Gaussians per depth-sorted chunk of a tile list, the other block side (16 was fastest)"))
    near: float = Field(0.01, gt=0.0, description="near plane (metres): Gaussians with camera depth below are culled")
    precision: str = Field("float32", pattern="^(float32|float64)$",
                           description="float dtype of rendering and fitting (float64 needs jax_enable_x64)")


SPECS = [
    ImplementationSpec(
        role="splat_renderer", name="jax", factory="pgc_jax.splat.renderer:JaxSplatRenderer",
        description="3DGS rasteriser in JAX/XLA: tile chunks composited densely, jit + grad; mesh-embedded fit",
        options="pgc_jax.specs_splat:JaxSplatOptions", requires=("jax",), extra="jax"),
]
