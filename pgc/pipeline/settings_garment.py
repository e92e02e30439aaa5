"""Options of the pipeline stage ``garment``: the garment sub-mesh (the simulator's rest shape and the texture's
domain) cut from the reconstructor's labelled full-body mesh, with its own UV atlas."""

from __future__ import annotations

from pydantic import Field

from pgc.options import Options


class GarmentSettings(Options):
    """Garment sub-mesh extraction (:func:`pgc.geometry.finish.extract_garment`)."""

    min_island_faces: int = Field(50, ge=0, description="label islands with fewer faces are absorbed by "
                                                         "their surroundings before extraction")
    uv_resolution: int = Field(1024, ge=64, le=16384, description="texture size the garment's own UV "
                                                                  "atlas is packed for (px)")
    uv_padding: int = Field(2, ge=0, le=64, description="texels between the garment's UV charts")

