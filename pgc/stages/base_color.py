"""Stage ``base_color``: the garment's albedo texture (albedo estimator, colour correction, UV merge;
:mod:`pgc.albedo.base_color`)."""

from __future__ import annotations

from pgc.options import Options, count
from pgc.stages.declaration import Stage


class BaseColorSettings(Options):
    texture_size: int = count(512, 16, 8192)
    """Side of the square albedo texture (texels)."""
    num_views: int = count(10, 1, 10_000)
    """Views merged into the texture (paper: 10), chosen greedily for coverage."""


STAGE = Stage(name="base_color", command="reconstruct", version="2", inputs=("capture", "mesh", "garment"),
              outputs=("base_color.npy",), folder="ASSET/stages/base_color", role="albedo_estimator",
              settings=BaseColorSettings, fingerprint_roles=("albedo_estimator",), events=("base_color",))
