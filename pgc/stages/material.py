"""Stage ``material``: the BRDF's parameters and the light's radiance, fitted by the PBR renderer under the
capture's light. Its settings live with the role's contract, which every backend reads."""

from pgc.roles.pbr_renderer import MaterialFitSettings
from pgc.stages.declaration import Stage

STAGE = Stage(name="material", command="reconstruct", version="4",
              inputs=("capture", "mesh", "garment", "base_color"), outputs=("material.json",),
              folder="ASSET/stages/material", role="pbr_renderer", roles=("pbr_renderer", "brdf"),
              settings=MaterialFitSettings, events=("material",))
