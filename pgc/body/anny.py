"""The ``anny`` body model: NAVER's Anny (MakeHuman data) with the CMU motion-capture rig, in PGC's frame.

Anny builds its model data from the data inside its wheel on first use and caches it in ``~/.cache/anny``
(``ANNY_CACHE_DIR``); ``scripts/setup.sh`` pays that build (:mod:`pgc.body.prepare`). Nothing here downloads:
the only downloads in Anny (its SMPL/SMPL-X correspondence files) are never called.

Anny's frame is Z-up with the person facing -Y; PGC's is Y-up facing +Z (:data:`ANNY_TO_PGC`). Skinning is
Anny's dense linear blend skinning in torch (differentiable in float32 and float64, no kernel compile).
"""

from __future__ import annotations

import copy
import functools
import logging
from typing import TYPE_CHECKING, Mapping

import numpy as np

from pgc.builtin_plugins.specs_body import AnnyOptions
from pgc.roles.body_model import BodyModel, BodyTensors, ShapeParameter, global_transforms_torch

if TYPE_CHECKING:
    import torch

log = logging.getLogger(__name__)

RIG = "cmu_mb"
"""Anny's rig with the joints of the CMU motion-capture skeleton."""

CMU_ASF_JOINTS: dict[str, str] = {
    "root": "Hips", "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1",
    "lowerneck": "Neck", "upperneck": "Neck1", "head": "Head",
    **{f"{s}{asf}": f"{side}{rig}" for s, side in (("l", "Left"), ("r", "Right"))
       for asf, rig in (("clavicle", "Shoulder"), ("humerus", "Arm"), ("radius", "ForeArm"), ("wrist", "Hand"),
                        ("hand", "FingerBase"), ("fingers", "HandFinger1"), ("femur", "UpLeg"), ("tibia", "Leg"),
                        ("foot", "Foot"), ("toes", "ToeBase"))},
    "lhipjoint": "LHipJoint", "rhipjoint": "RHipJoint", "lthumb": "LThumb", "rthumb": "RThumb",
}
"""CMU ASF/AMC bone name -> joint of the ``cmu_mb`` rig (the MotionBuilder-friendly names of CMU's BVH release).
A rig joint sits where its ASF bone starts and rotates what that bone carries."""

ANNY_TO_PGC = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
"""Rotation taking Anny's Z-up, -Y-facing coordinates to PGC's Y-up, +Z-facing ones (x stays the person's
left)."""

PHENOTYPES: dict[str, ShapeParameter] = {
    "gender": ShapeParameter(0.0, 1.0, 0.5, "0 male, 1 female"),
    "age": ShapeParameter(0.0, 1.0, 2.0 / 3.0, "0 baby, 1/3 child, 2/3 young adult (25 years), 1 old"),
    "muscle": ShapeParameter(0.0, 1.0, 0.5, "0 least, 0.5 average, 1 most muscular"),
    "weight": ShapeParameter(0.0, 1.0, 0.5, "0 lightest, 0.5 average, 1 heaviest"),
    "height": ShapeParameter(0.0, 1.0, 0.5, "0 shortest, 1 tallest for the age and gender"),
    "proportions": ShapeParameter(0.0, 1.0, 0.5, "0 ideal, 1 uncommon proportions"),
}
"""Anny's phenotypes (its default set), with PGC's default: an adult of average build."""


def import_anny():
    """The ``anny`` package, imported (with torch; several seconds on a cold start)."""
    import anny

    return anny


@functools.lru_cache(maxsize=4)
def build_anny(topology: str, dtype_name: str = "float64"):
    """Anny with the CMU rig and ``topology``, in ``dtype_name`` (cached per process; the first build on a machine
    fills Anny's disk cache: docs/body.md has the times)."""
    import torch

    anny = import_anny()
    if dtype_name != "float64":  # Anny's own dtype
        return copy.deepcopy(build_anny(topology)).to(getattr(torch, dtype_name))
    from anny.paths import get_anny_cache_path

    if not any(get_anny_cache_path().glob("v*/load_data_*.safetensors")):
        log.warning("Anny builds its model data once (minutes, about 550 MB) into %s; scripts/setup.sh does this "
                    "at install time", get_anny_cache_path())
    return anny.Anny(rig=RIG, topology=topology, skinning_method="lbs")


class AnnyBody(BodyModel):
    """Anny's body, phenotypes gender, age, muscle, weight, height and proportions, rigged with CMU's joints."""

    Options = AnnyOptions
    parameters = PHENOTYPES

    def __init__(self, options: AnnyOptions | dict | None = None) -> None:
        super().__init__(options)
        self._model = build_anny(self.options.topology)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self._model.bone_labels)

    @property
    def parents(self) -> np.ndarray:
        return np.asarray(self._model.bone_parents, dtype=np.int64)

    @functools.cached_property
    def faces(self) -> np.ndarray:
        return self._model.faces.cpu().numpy().astype(np.int64)

    @functools.cached_property
    def weights(self) -> np.ndarray:
        return self._model.dense_vertex_bone_weights.cpu().numpy().astype(np.float64)

    def forward_torch(self, shape: Mapping[str, "torch.Tensor"], rotations: "torch.Tensor",
                      translation: "torch.Tensor") -> BodyTensors:
        import torch

        model = build_anny(self.options.topology, str(rotations.dtype).removeprefix("torch."))
        coeffs = model.get_phenotype_blendshape_coefficients(**{k: shape[k].to(rotations.dtype) for k in PHENOTYPES})
        rest = model.get_rest_model(coeffs)
        to_pgc = torch.as_tensor(ANNY_TO_PGC, dtype=rotations.dtype)
        vertices = rest["rest_vertices"] @ to_pgc.T
        joints = rest["rest_bone_heads"] @ to_pgc.T
        ground = torch.stack([-joints[:, 0, 0], -vertices[..., 1].min(dim=1).values, -joints[:, 0, 2]], dim=1)
        vertices, joints = vertices + ground[:, None], joints + ground[:, None]
        transforms = global_transforms_torch(joints, self.parents, rotations, translation)
        posed = model.get_skinned_vertices(vertices.expand(len(transforms), -1, -1), transforms)
        posed_joints = transforms[..., :3, :3] @ joints[..., None]
        return BodyTensors(posed, posed_joints[..., 0] + transforms[..., :3, 3], transforms)
