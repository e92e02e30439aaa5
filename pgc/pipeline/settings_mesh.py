"""Options of the pipeline stage ``mesh`` (light module): what happens after the reconstructor returns the
labelled full-body mesh: the garment sub-mesh that the simulator and the asset use."""

from __future__ import annotations

from pydantic import Field

from pgc.options import Options


class MeshStageOptions(Options):
    """Garment sub-mesh extraction (pgc_meshlab.finish.extract_garment)."""

    garment_min_island_faces: int = Field(50, ge=0, description="label islands with fewer faces are absorbed by "
                                                                 "their surroundings before extraction")
    garment_uv_resolution: int = Field(1024, ge=64, le=16384, description="texture size the garment's own UV "
                                                                          "atlas is packed for (px)")
    garment_uv_padding: int = Field(2, ge=0, le=64, description="texels between the garment's UV charts")


SETTINGS = {"mesh": MeshStageOptions}
