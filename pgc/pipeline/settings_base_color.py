"""Options of the base-colour texture stage."""

from pydantic import Field

from pgc.options import Options


class BaseColorSettings(Options):
    texture_size: int = Field(512, ge=16, le=8192)
    """Side of the square albedo texture (texels)."""
    num_views: int = Field(10, ge=1)
    """Views merged into the texture (paper: 10), chosen greedily for coverage."""

