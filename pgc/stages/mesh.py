"""Stage ``mesh``: the reconstructor's labelled full-body mesh with UVs (configured by ``[reconstructor]``)."""

from pgc.stages.declaration import Stage

STAGE = Stage(name="mesh", command="reconstruct", version="4", inputs=("capture",), outputs=("mesh.npz",),
              folder="ASSET/stages/mesh", role="reconstructor", events=("mesh.*",))
