"""Registration of the built-in reconstructors 'visual_hull' and 'mesh' (light: pgc core + pydantic only).

Both finish their surface with :mod:`pgc.geometry.finish`, which needs pymeshlab and xatlas (``pgc[meshlab]``)."""

from __future__ import annotations

from pydantic import Field, field_validator

from pgc.geometry.options import FinishOptions
from pgc.registry import ImplementationSpec


class VisualHullOptions(FinishOptions):
    """The visual hull of the masks, finished like every reconstruction (fast baseline)."""

    voxel_px: float = Field(1.0, gt=0.05, le=16.0, description="hull voxel size in pixel footprints at the object")


class MeshFileOptions(FinishOptions):
    """A user's own scan or mesh (OBJ, PLY, glTF/GLB) in the capture's frame, or brought there."""

    path: str = Field(..., min_length=1, description="mesh file (.obj, .ply, .glb, .gltf)")
    transform: list[float] | None = Field(None, description="optional 4x4 row-major matrix (16 numbers) taking "
                                                            "file coordinates to the capture frame (metres)")
    refine_alignment: bool = Field(False, description="refine the pose by rigid ICP onto the visual hull")
    remesh: bool = Field(True, description="clean and remesh to target_vertices; False keeps the file's "
                                           "topology apart from repairs (labels and UVs are still computed)")
    min_silhouette_iou: float = Field(0.5, ge=0.0, le=1.0, description="fail when the mesh's silhouettes "
                                                                       "overlap the masks less than this (IoU)")

    @field_validator("transform")
    @classmethod
    def _sixteen(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and len(v) != 16:
            raise ValueError(f"transform needs 16 numbers (a row-major 4x4 matrix), got {len(v)}")
        return v


_REQ = ("pymeshlab", "xatlas")
"""What :mod:`pgc.geometry.finish` imports (numpy, scipy and trimesh are core dependencies)."""

SPECS = [
    ImplementationSpec(
        role="reconstructor", name="visual_hull", factory="pgc.builtin_plugins.reconstructors:VisualHullReconstructor",
        description="visual hull of the masks (silhouette distance field + surface nets); fast baseline",
        options="pgc.builtin_plugins.specs_reconstruct:VisualHullOptions", requires=_REQ, extra="meshlab"),
    ImplementationSpec(
        role="reconstructor", name="mesh", factory="pgc.builtin_plugins.reconstructors:MeshFileReconstructor",
        description="a user's own scan or mesh (OBJ/PLY/glTF) aligned to the capture frame",
        options="pgc.builtin_plugins.specs_reconstruct:MeshFileOptions", requires=_REQ, extra="meshlab"),
]
