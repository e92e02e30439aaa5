"""Stage ``fit_splats``: mesh-embedded Gaussians fitted on the full mesh by the splat renderer (only the
garment's are kept in the asset). Its settings live with the role's contract, which every backend reads."""

from pgc.roles.splat_renderer import FitSplatsSettings
from pgc.stages.declaration import Stage

STAGE = Stage(name="fit_splats", command="reconstruct", version="4", inputs=("capture", "mesh"),
              outputs=("gaussians_full.npz", "heldout_views.json"), folder="ASSET/stages/fit_splats",
              role="splat_renderer", settings=FitSplatsSettings, events=("fit_splats",))
