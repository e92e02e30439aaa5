"""Spec and options of the fast PBR renderer (role ``pbr_renderer``, name ``torch``). Light module."""

from typing import Literal

from pydantic import Field

from pgc.options import MAX_THREADS, Options, count
from pgc.registry import ImplementationSpec


class TorchPBROptions(Options):
    directions: int = Field(256, ge=8, le=16384)
    """Number of lighting directions (a spherical Fibonacci set, equal solid angles) the environment is
    integrated over; the environment map is averaged over each direction's cell."""
    visibility_at: Literal["vertex", "point"] = "vertex"
    """Where occlusion is ray cast: once per mesh vertex (interpolated; fast, reused across views) or at
    every shaded texel/pixel (exact positions; slower)."""
    indirect: bool = True
    """Occluded directions receive the light reflected by the scene, approximated as mean base colour x
    mean unoccluded radiance (one diffuse bounce); False: they are black (direct light only)."""
    smooth_normals: bool = True
    """Shade with interpolated vertex normals (False: flat faces)."""
    ray_offset: float = Field(1e-4, gt=0.0)
    """Occlusion rays start this far above the surface (fraction of the bounding-box diagonal)."""
    threads: int = count(0, 0, MAX_THREADS)
    """torch intra-op threads while shading (restored afterwards); 0 keeps torch's setting. On a loaded
    machine 1 thread can be ~10x faster than contended OpenMP threads."""
    chunk: int = count(4096, 64, 1 << 24)
    """Points shaded per torch batch (memory ~ chunk x directions x 3 floats)."""


SPECS = [
    ImplementationSpec(
        role="pbr_renderer", name="torch", factory="pgc_torch.pbr.renderer:TorchPBRRenderer",
        description="fast approximation: environment light over a fixed direction set with ray-cast "
                    "visibility (Open3D) and a one-bounce ambient term, analytic BRDF shading in torch",
        options="pgc_torch.specs_pbr:TorchPBROptions", requires=("torch", "open3d"), extra="torch"),
]
