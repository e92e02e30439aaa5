"""Options shared by every reconstructor: the finishing steps (clean, remesh, UVs, labels). Light module."""

from __future__ import annotations

from pydantic import Field, field_validator

from pgc.io.limits import MAX_VIEWS
from pgc.options import Options, count


class FinishOptions(Options):
    """Finishing of a raw surface into a simulation-quality, UV-mapped, labelled mesh."""

    target_vertices: int = count(15_000, 100, 2_000_000, "vertex count of the isotropic remesh (paper: 11-18k)")
    remesh_iterations: int = count(6, 1, 50, "isotropic remeshing iterations per pass")
    min_component_fraction: float = Field(0.02, ge=0.0, le=1.0,
                                          description="drop connected components with fewer faces than this "
                                                      "fraction of the largest one")
    max_hole_edges: int = count(1000, 0, 1_000_000, "close holes bounded by at most this many edges")
    uv_resolution: int = count(1024, 64, 16384, "texture size the UV atlas is packed for (px)")
    uv_padding: int = count(2, 0, 64, "texels between UV charts")
    label_depth_tolerance_px: float = Field(1.5, gt=0.0, description="visibility test tolerance of the label "
                                                                       "vote, in pixel footprints")
    label_smooth_iterations: int = count(2, 0, 20, "majority-filter passes over face labels")
    label_min_evidence: float = Field(0.05, ge=0.0, le=1.0, description=(
        "share of the median face's evidence (the summed cosines of the views that see it) a face needs to count "
        "as observed by the label vote; an unobserved region beside the body is body (the hull's closure of a "
        "garment's opening)"))
    min_views: int = count(4, 2, MAX_VIEWS, "fewest views a capture must have")


class DenseOptions(FinishOptions):
    """Multi-view stereo (plane sweep guided by the visual hull), shared by the open3d and colmap reconstructors."""

    stereo_views: int = count(64, 0, MAX_VIEWS, (
        "views that get a depth map, evenly spread over the capture (the visual hull uses every view); stereo's "
        "time grows with them, and 64 gives captures of up to 64 views the mesh they had before the option; "
        "0 = every view"))
    neighbours: int = count(6, 1, 32, "neighbour views per reference view (among stereo_views)")
    top_k: int = count(3, 1, 32, "best neighbours averaged per depth hypothesis")
    window: int = count(7, 3, 31, "NCC window side (pixels, odd)")
    band: float = Field(0.12, gt=0.0, description="depth range swept behind the visual hull (metres)")
    step_px: float = Field(0.5, gt=0.0, le=4.0, description="depth step in pixel footprints")
    min_score: float = Field(0.5, ge=-1.0, le=1.0, description="lowest accepted NCC")
    min_consistent: int = count(2, 0, 32, "neighbour depth maps that must agree with a depth (at most neighbours)")
    consistency: float = Field(0.01, gt=0.0, description="relative depth agreement of the consistency check")
    hull_tolerance: float = Field(0.05, ge=0.0, le=2.0, description="keep the visual hull's depth where its NCC "
                                                                    "is within this of the best hypothesis")
    poisson_cell_px: float = Field(0.5, gt=0.05, le=4.0, description="Poisson octree cell in pixel footprints "
                                                                     "(sets the depth when none is given)")
    hull_fill: bool = Field(True, description="add visual-hull surface points where stereo found none "
                                               "(the hull bounds the surface; exact where it is convex)")
    hull_margin_px: float = Field(2.0, ge=0.0, description="trim surface parts farther than this many pixel "
                                                            "footprints outside the visual hull")

    @field_validator("stereo_views")
    @classmethod
    def _zero_or_a_pair(cls, v: int) -> int:
        if v == 1:
            raise ValueError("stereo needs at least 2 views: set stereo_views = 0 (every view) or >= 2")
        return v

    def stereo(self):
        """The matching :class:`pgc.geometry.stereo.StereoSettings`."""
        from pgc.geometry.stereo import StereoSettings

        return StereoSettings(neighbours=self.neighbours, top_k=self.top_k, window=self.window | 1,
                              band=self.band, step_px=self.step_px, min_score=self.min_score,
                              min_consistent=self.min_consistent, consistency=self.consistency,
                              hull_tolerance=self.hull_tolerance)
