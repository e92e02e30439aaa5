"""Joint-name maps from motion-capture skeletons to body rigs, and the choice of a default.

A map sends a clip joint to the rig joint at the same place: the joint whose rotation turns the same bone
(CMU's ``lhumerus`` starts at the shoulder and turns the upper arm, as the synthetic body's ``l_shoulder``).
"""

from __future__ import annotations

from pgc.errors import PGCDataError

_SIDES = (("l", "l", "Left"), ("r", "r", "Right"))

CMU_TO_SYNTH: dict[str, str] = {
    "root": "pelvis", "lowerback": "spine1", "upperback": "spine2", "thorax": "spine3", "lowerneck": "neck",
    "head": "head",
    **{f"{c}{bone}": f"{s}_{joint}" for c, s, _ in _SIDES for bone, joint in (
        ("clavicle", "clavicle"), ("humerus", "shoulder"), ("radius", "elbow"), ("wrist", "wrist"),
        ("hand", "hand"), ("femur", "hip"), ("tibia", "knee"), ("foot", "ankle"), ("toes", "foot"))},
}
"""CMU ASF bone names (CMU's joints) -> joints of the synthetic body (:mod:`pgc.synth.skeleton`)."""

BVH_TO_SYNTH: dict[str, str] = {
    "Hips": "pelvis", "Spine": "spine1", "Spine1": "spine2", "Spine2": "spine3", "Neck": "neck", "Head": "head",
    **{f"{word}{bone}": f"{s}_{joint}" for _, s, word in _SIDES for bone, joint in (
        ("Shoulder", "clavicle"), ("Arm", "shoulder"), ("ForeArm", "elbow"), ("Hand", "wrist"),
        ("UpLeg", "hip"), ("Leg", "knee"), ("Foot", "ankle"), ("ToeBase", "foot"))},
}
"""The common BVH naming (CMU's BVH conversions, Mixamo without its prefix) -> the synthetic body's joints."""

CANDIDATES: dict[str, dict[str, str]] = {
    "cmu->synthetic": CMU_TO_SYNTH,
    "bvh->synthetic": BVH_TO_SYNTH,
    "cmu->cmu": {name: name for name in CMU_TO_SYNTH},
    "bvh->bvh": {name: name for name in BVH_TO_SYNTH},
}
"""Default maps, tried in turn: the one whose joints both skeletons have wins."""


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
                           "the clip's joints to the rig's (pgc.motion.retarget.retarget(joint_map=...))")
    if len(set(joint_map.values())) != len(joint_map):
        raise PGCDataError(f"{source}: joints: the joint map sends two clip joints to one rig joint")
    if rig_names[0] not in joint_map.values():
        raise PGCDataError(f"{source}: joints: the joint map must give the rig's root '{rig_names[0]}' a clip joint")
    return dict(joint_map)
