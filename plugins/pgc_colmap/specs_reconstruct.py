"""Registration of the colmap reconstructor (light: no pycolmap import)."""

from __future__ import annotations

from pydantic import Field

from pgc.geometry.options import DenseOptions
from pgc.io.limits import MAX_VIEWS
from pgc.options import count
from pgc.registry import ImplementationSpec


class ColmapReconstructorOptions(DenseOptions):
    """COLMAP on the CPU: SIFT features, exhaustive matching, triangulation with the known poses (its shared
    points tell fusion which views overlap; its reprojection error checks the calibration), stereo fusion of our plane-sweep depth maps (COLMAP's PatchMatch needs CUDA) and
    COLMAP's screened Poisson meshing; then trimmed by the visual hull and finished."""

    poisson_depth: int | None = Field(None, ge=5, le=12, description="octree depth; None matches the pixel footprint")
    poisson_trim: float = Field(0.0, ge=0.0, le=20.0, description="COLMAP's density trim (0: none; the visual hull "
                                                                   "trims instead)")
    fusion_min_pixels: int = count(3, 1, MAX_VIEWS, "views that must agree on a fused point")
    fusion_max_reproj_error: float = Field(2.0, gt=0.0, description="pixels")
    fusion_max_depth_error: float = Field(0.01, gt=0.0, description="relative depth error")
    fusion_max_normal_error: float = Field(10.0, gt=0.0, description="degrees")
    max_features: int = count(4096, 64, 1_000_000, "SIFT features per image")
    sift_peak_threshold: float = Field(0.002, gt=0.0, description="SIFT peak threshold (COLMAP's default 0.0067 "
                                                                  "finds few features on small cloth images)")
    min_inliers: int = count(12, 6, 1_000_000, "verified matches a view pair needs")




SPECS = [
    ImplementationSpec(
        role="reconstructor", name="colmap", factory="pgc_colmap.reconstruct:ColmapReconstructor",
        description="pycolmap on CPU: SIFT + triangulation with known poses, stereo_fusion of our depth maps, "
                    "poisson_meshing; trimmed by the visual hull",
        options="pgc_colmap.specs_reconstruct:ColmapReconstructorOptions",
        requires=("pycolmap", "cv2", "pymeshlab", "xatlas"), extra="colmap"),
]
