"""Stage ``garment``: the garment sub-mesh (the simulator's rest shape and the texture's domain) cut from the
reconstructor's labelled full-body mesh, with its own UV atlas."""

from __future__ import annotations

from pgc.options import Options, count
from pgc.stages.declaration import Stage


class GarmentSettings(Options):
    """Garment sub-mesh extraction (:func:`pgc.geometry.finish.extract_garment`)."""

    min_island_faces: int = count(50, 0, 10_000_000, "label islands with fewer faces are absorbed by their "
                                                      "surroundings before extraction")
    uv_resolution: int = count(1024, 64, 16384, "texture size the garment's own UV atlas is packed for (px)")
    uv_padding: int = count(2, 0, 64, "texels between the garment's UV charts")


STAGE = Stage(name="garment", command="reconstruct", version="2", inputs=("mesh", "garment_labels"),
              outputs=("garment.npz", "selection.npy"), folder="ASSET/stages/garment", settings=GarmentSettings)
