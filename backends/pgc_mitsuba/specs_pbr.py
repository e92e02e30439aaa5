"""Spec and options of the path-traced PBR renderer (role ``pbr_renderer``, name ``mitsuba``). Light module."""

from pydantic import Field

from pgc.options import Options, count, seed_field
from pgc.registry import ImplementationSpec


class MitsubaPBROptions(Options):
    spp: int = count(64, 1, 65536)
    """Samples per pixel (screen space) or per texel (texture space) when rendering."""
    max_depth: int = count(4, 2, 64)
    """Maximum path length (Mitsuba convention: 2 = direct light only; 4 = up to two indirect bounces)."""
    smooth_normals: bool = True
    """Shade with interpolated vertex normals (False: flat faces)."""
    ray_offset: float = Field(1e-4, gt=0.0)
    """Texture space: ray origins lie this far from the texel toward the camera centre, as a fraction of
    the mesh's bounding-box diagonal."""
    max_samples_per_pass: int = count(4_000_000, 1024, 1 << 30)
    """Rays traced per Mitsuba render call; larger renders are split into passes (bounds memory)."""
    occluder_albedo: float = Field(0.5, ge=0.0, le=1.0)
    """Albedo of non-garment faces of a labelled mesh (the body), which shadow and inter-reflect."""
    seed: int = seed_field()


SPECS = [
    ImplementationSpec(
        role="pbr_renderer", name="mitsuba", factory="pgc_mitsuba.pbr:MitsubaPBRRenderer",
        description="Mitsuba 3 path tracer (LLVM, CPU): shadows and indirect light, constant or environment "
                    "light, screen and texture space; fits BRDF parameters + light by differentiable rendering",
        options="pgc_mitsuba.specs_pbr:MitsubaPBROptions", requires=("mitsuba", "drjit"), extra="mitsuba"),
]
