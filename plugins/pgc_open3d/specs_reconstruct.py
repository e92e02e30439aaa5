"""Registration of the open3d reconstructor (light: no open3d import)."""

from __future__ import annotations

from pydantic import Field

from pgc.geometry.options import DenseOptions
from pgc.registry import ImplementationSpec


class Open3DReconstructorOptions(DenseOptions):
    """Hull-guided plane-sweep stereo -> oriented points -> Open3D screened Poisson, trimmed."""

    poisson_depth: int | None = Field(None, ge=5, le=12, description="octree depth of screened Poisson; None "
                                                                     "chooses the depth whose cell matches the "
                                                                     "pixel footprint")
    density_quantile: float = Field(0.02, ge=0.0, lt=1.0, description="trim Poisson vertices whose point "
                                                                        "density is below this quantile")


SPECS = [
    ImplementationSpec(
        role="reconstructor", name="open3d", factory="pgc_open3d.reconstruct:Open3DReconstructor",
        description="hull-guided plane-sweep stereo + Open3D screened Poisson, trimmed by density and the visual hull",
        options="pgc_open3d.specs_reconstruct:Open3DReconstructorOptions",
        requires=("open3d", "cv2", "pymeshlab", "xatlas"), extra="open3d"),
]
