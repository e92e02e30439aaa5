"""Options of the base-colour texture stage."""

from pgc.options import Options, count


class BaseColorSettings(Options):
    texture_size: int = count(512, 16, 8192)
    """Side of the square albedo texture (texels)."""
    num_views: int = count(10, 1, 10_000)
    """Views merged into the texture (paper: 10), chosen greedily for coverage."""

