"""Captured motion clips: ASF/AMC and BVH parsing, forward kinematics, the BVH round trip, retargeting,
resampling and the blend from the capture pose (pgc.motion)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.motion.asf import amc_clip, bone_end_positions, read_amc, read_amc_clip, read_asf
from pgc.motion.bvh import read_bvh, write_bvh
from pgc.motion.clip import Clip, Skeleton
from pgc.motion.drive import load_clip, shipped_clip, shipped_clips
from pgc.body.anny import CMU_ASF_JOINTS
from pgc.motion.retarget import (ARM_SPACE_DEG, Rig, RigMotion, keep_arms_clear, resample, retarget,
                                 start_at_capture, trim)
from pgc.motion.rotations import axis_rotation, euler_to_matrix, matrix_to_quaternion, quaternion_to_matrix

CMU = shipped_clips()
CLIPS = {"02_01": 343, "02_03": 173, "02_04": 300, "02_05": 360}


def bone_end_joint(clip: Clip, asf, bone: str) -> int:
    """The clip joint at the end of ``bone``: its first child's start, or its end joint."""
    kids = asf.children.get(bone)
    return clip.skeleton.index(kids[0] if kids else f"{bone}_end")


@pytest.fixture(scope="module")
def rig(default_body_model):
    """Anny's cmu_mb rig in its rest A-pose (the capture pose)."""
    r = default_body_model.rig()
    return Rig(r.names, r.parents, r.joints)


@pytest.fixture(scope="module")
def walk():
    asf = read_asf(CMU / "02.asf")
    amc = read_amc(CMU / "02_01.amc", asf)
    return asf, amc, amc_clip(asf, amc)


# parsing --------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(CLIPS))
def test_shipped_clips_parse(name):
    clip = read_amc_clip(CMU / f"{name}.amc")
    assert clip.num_frames == CLIPS[name] and clip.fps == 120.0
    assert len(clip.skeleton.names) == 1 + 30 + 7  # root, 30 bones, end joints of toes, head, fingers, thumbs
    assert np.all(np.isfinite(clip.rotations)) and np.all(np.isfinite(clip.root_translation))
    r = clip.rotations
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)


def test_asf_units_give_a_person_in_metres():
    """CMU's 'length 0.45': 1 unit = 1/0.45 inch; subject 2's femur 7.59371 units is 0.4286 m."""
    asf = read_asf(CMU / "02.asf")
    assert asf.metres_per_unit == pytest.approx(0.0254 / 0.45)
    assert asf.bones["lfemur"].length == pytest.approx(7.59371 * 0.0254 / 0.45)
    assert 0.38 < asf.bones["lfemur"].length < 0.50 and 0.35 < asf.bones["ltibia"].length < 0.48
    assert asf.bones["lfemur"].dof == ("rx", "ry", "rz") and asf.bones["ltibia"].dof == ("rx",)
    # CMU bones lie along an axis of their own frame: C^T d = -Y for the limbs
    for name in ("lfemur", "ltibia", "lhumerus", "rradius", "lwrist"):
        b = asf.bones[name]
        np.testing.assert_allclose(b.axis.T @ b.direction, [0, -1, 0], atol=1e-6)
    rest = read_amc_clip(CMU / "02_01.amc").skeleton.rest_positions()
    assert 1.5 < rest[:, 1].max() - rest[:, 1].min() < 1.8  # T-pose: head top to toes


def test_clip_joints_are_the_acclaim_forward_kinematics(walk):
    asf, amc, clip = walk
    ends = bone_end_positions(asf, amc)
    pos = clip.joint_positions()
    for bone in asf.order():
        np.testing.assert_allclose(pos[:, bone_end_joint(clip, asf, bone)], ends[bone], atol=1e-12)
    np.testing.assert_allclose(pos[:, 0], ends["root"], atol=1e-12)


def test_subject_skeleton_found_or_given(tmp_path):
    (tmp_path / "take.amc").write_bytes((CMU / "02_03.amc").read_bytes())
    with pytest.raises(PGCDataError, match=r"take\.asf.*--skeleton"):
        load_clip(tmp_path / "take.amc")
    from pgc.motion.drive import ClipOptions

    clip = load_clip(tmp_path / "take.amc", ClipOptions(skeleton=CMU / "02.asf", fps=60.0))
    assert clip.fps == 60.0 and clip.num_frames == 173
    assert shipped_clip("cmu:02_03.bvh").name == "02_03.bvh" and shipped_clip("cmu:02_04").name == "02_04.amc"
    with pytest.raises(PGCDataError, match="no shipped clip"):
        shipped_clip("cmu:99_99")


# forward kinematics: analytic cases ---------------------------------------------------------------------

ASF_CHAIN = """:version 1.10
:name chain
:units
  mass 1.0
  length 0.0254
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name upper
     direction 0 -1 0
     length 0.5
     axis 0 0 0 XYZ
    dof rx rz
    limits (-180 180)
           (-180 180)
  end
  begin
     id 2
     name lower
     direction 0 -1 0
     length 0.4
     axis 0 0 90 XYZ
    dof rx
    limits (-180 180)
  end
:hierarchy
  begin
    root upper
    upper lower
  end
"""


def write_chain(tmp_path, frames: list[str], asf: str = ASF_CHAIN) -> tuple:
    (tmp_path / "chain.asf").write_text(asf)
    body = ":FULLY-SPECIFIED\n:DEGREES\n" + "".join(f"{t + 1}\n{f}\n" for t, f in enumerate(frames))
    (tmp_path / "chain_01.amc").write_text(body)
    return tmp_path / "chain.asf", tmp_path / "chain_01.amc"


def test_two_bone_chain_matches_the_analytic_positions(tmp_path):
    """'length 0.0254' makes 1 unit = 1 m. Upper (0.5 m down, dofs rx rz), lower (0.4 m down, its frame turned
    90 degrees about Z, dof rx: about the frame's x, which is world +Y, the bone's own axis in the rest pose)."""
    asf, amc = write_chain(tmp_path, ["root 1 2 3 0 0 0\nupper 90 0\nlower 0",
                                      "root 0 0 0 0 0 90\nupper 0 0\nlower 0",
                                      "root 0 0 0 0 0 0\nupper 0 90\nlower 0",
                                      "root 0 0 0 0 0 0\nupper 90 90\nlower 0",
                                      "root 0 0 0 0 0 0\nupper 0 90\nlower 90"])
    clip = read_amc_clip(amc)
    pos = clip.joint_positions()
    names = clip.skeleton.names
    assert names == ("root", "upper", "lower", "lower_end")
    knee, tip = pos[:, names.index("lower")], pos[:, names.index("lower_end")]
    # frame 0: rx 90 swings the chain from -Y to -Z, root moved to (1, 2, 3)
    np.testing.assert_allclose(knee[0], [1, 2, 3 - 0.5], atol=1e-12)
    np.testing.assert_allclose(tip[0], [1, 2, 3 - 0.9], atol=1e-12)
    # frame 1: the root turned 90 degrees about Z: -Y goes to +X
    np.testing.assert_allclose(tip[1], [0.9, 0, 0], atol=1e-12)
    # frame 2: rz 90 on the upper bone: the chain points +X
    np.testing.assert_allclose(knee[2], [0.5, 0, 0], atol=1e-12)
    # frame 3: rx first, then rz: -Y -> (rx 90) -Z -> (rz 90) -Z
    np.testing.assert_allclose(tip[3], [0, 0, -0.9], atol=1e-12)
    # frame 4: the lower bone's rx is about its frame's x = world +Y (C = Rz 90), then the upper's rz 90: the
    # lower bone (along -Y at rest) twists about its own axis, so it still points where the upper one does
    np.testing.assert_allclose(tip[4], [0.9, 0, 0], atol=1e-12)


def test_bvh_rotation_orders_compose_in_the_listed_order(tmp_path):
    """A two-bone BVH chain with 'Zrotation Xrotation Yrotation' on the hip: R = Rz Rx Ry."""
    angles = np.deg2rad([30.0, 40.0, 50.0])  # z, x, y as written
    text = ("HIERARCHY\nROOT hip\n{\n OFFSET 0 100 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation "
            "Xrotation Yrotation\n JOINT knee\n {\n  OFFSET 0 -50 0\n  CHANNELS 3 Yrotation Zrotation Xrotation\n"
            "  End Site\n  {\n   OFFSET 0 -40 0\n  }\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.04\n"
            f"10 0 0 30 40 50 0 90 0\n")
    (tmp_path / "chain.bvh").write_text(text)
    clip = read_bvh(tmp_path / "chain.bvh")
    assert clip.fps == pytest.approx(25.0) and clip.skeleton.names == ("hip", "knee", "knee_end")
    pos = clip.joint_positions()[0]
    hip_rot = axis_rotation("Z", angles[0]) @ axis_rotation("X", angles[1]) @ axis_rotation("Y", angles[2])
    np.testing.assert_allclose(pos[0], [0.1, 1.0, 0], atol=1e-12)
    np.testing.assert_allclose(pos[1], [0.1, 1.0, 0] + hip_rot @ [0, -0.5, 0], atol=1e-12)
    knee_rot = axis_rotation("Z", np.pi / 2)  # Y 0, Z 90, X 0
    np.testing.assert_allclose(pos[2], pos[1] + hip_rot @ knee_rot @ [0, -0.4, 0], atol=1e-12)


# BVH round trip --------------------------------------------------------------------------------------------

def test_bvh_write_read_gives_the_same_forward_kinematics(walk, tmp_path):
    _, _, clip = walk
    write_bvh(tmp_path / "walk.bvh", clip)
    back = read_bvh(tmp_path / "walk.bvh")
    assert set(back.skeleton.names) == set(clip.skeleton.names) and back.num_frames == clip.num_frames
    assert back.fps == pytest.approx(120.0, rel=1e-9)
    order = [back.skeleton.index(n) for n in clip.skeleton.names]
    err = np.abs(back.joint_positions()[:, order] - clip.joint_positions())
    assert err.max() < 1e-6, err.max()


def test_shipped_bvh_is_its_amc():
    amc, bvh = read_amc_clip(CMU / "02_03.amc"), read_bvh(CMU / "02_03.bvh")
    order = [bvh.skeleton.index(n) for n in amc.skeleton.names]
    assert np.abs(bvh.joint_positions()[:, order] - amc.joint_positions()).max() < 1e-6


def test_euler_writer_handles_gimbal_lock(tmp_path):
    sk = Skeleton(("a", "b", "b_end"), np.array([-1, 0, 1]), np.array([[0, 1.0, 0], [0, -0.5, 0], [0, -0.4, 0]]))
    rng = np.random.default_rng(0)
    rot = euler_to_matrix(rng.uniform(-3, 3, (6, 3, 3)), "ZYX")
    rot[:, 2] = np.eye(3)
    rot[0, 1] = euler_to_matrix(np.array([0.3, np.pi / 2, -0.7]), "ZYX")  # y = +90 degrees
    rot[1, 1] = euler_to_matrix(np.array([0.3, -np.pi / 2, -0.7]), "ZYX")  # y = -90 degrees
    clip = Clip(sk, rng.normal(size=(6, 3)) * 0.1, rot, 30.0, "test")
    write_bvh(tmp_path / "g.bvh", clip)
    back = read_bvh(tmp_path / "g.bvh")
    np.testing.assert_allclose(back.rotations, clip.rotations, atol=1e-8)


# retargeting ---------------------------------------------------------------------------------------------

def test_motion_round_trip_onto_the_asf_skeleton_rig(walk):
    """AMC -> retarget onto a rig built from the ASF's own skeleton -> joint positions, against the Acclaim
    forward kinematics of the ASF/AMC (the figure in docs/simulation.md)."""
    asf, amc, clip = walk
    sk = clip.skeleton
    rig = Rig(sk.names, sk.parents, sk.rest_positions())
    motion = retarget(clip, rig, {n: n for n in sk.names})
    pos = motion.joint_positions(rig)
    ends = bone_end_positions(asf, amc)
    err = np.concatenate([np.linalg.norm(pos[:, bone_end_joint(clip, asf, b)] - ends[b], axis=-1)
                          for b in asf.order()])
    assert err.max() < 1e-6, (err.max(), err.mean())


def test_retarget_points_every_mapped_bone_where_the_clip_does(walk, rig):
    """Onto Anny's A-pose rig: each rig bone (a mapped joint to its first mapped child) takes the direction of
    the clip's bone between the same joints, in every frame, where that is one clip bone."""
    JOINTS, PARENTS = rig.names, rig.parents
    _, _, clip = walk
    pos = retarget(clip, rig).joint_positions(rig)
    clip_pos = clip.joint_positions()
    to_clip = {r: clip.skeleton.index(c) for c, r in CMU_ASF_JOINTS.items()}
    checked = 0
    for j, name in enumerate(JOINTS):
        child = next((k for k in range(j + 1, len(JOINTS)) if PARENTS[k] == j), None)
        if PARENTS[j] < 0 or child is None or clip.skeleton.parents[to_clip[JOINTS[child]]] != to_clip[name]:
            continue
        d_rig = pos[:, child] - pos[:, j]
        d_clip = clip_pos[:, to_clip[JOINTS[child]]] - clip_pos[:, to_clip[name]]
        if np.linalg.norm(d_clip, axis=-1).min() < 1e-6 or np.linalg.norm(d_rig, axis=-1).min() < 1e-6:
            continue  # a zero-length bone has no direction
        np.testing.assert_allclose(d_rig / np.linalg.norm(d_rig, axis=-1, keepdims=True),
                                   d_clip / np.linalg.norm(d_clip, axis=-1, keepdims=True), atol=1e-9)
        checked += 1
    assert checked >= 20, checked


def test_a_clip_whose_joints_the_rig_lacks_is_refused(walk):
    _, _, clip = walk
    rig = Rig(("hips", "chest", "skull"), np.array([-1, 0, 1]), np.array([[0, 1.0, 0], [0, 1.3, 0], [0, 1.6, 0]]))
    with pytest.raises(PGCDataError, match=r"02_01\.amc: joints: .*the rig lacks .*Hips.*Give a joint map"):
        retarget(clip, rig)
    with pytest.raises(PGCDataError, match="the clip lacks nose"):
        retarget(clip, rig, {"root": "hips", "nose": "skull"})


# resampling and the blend --------------------------------------------------------------------------------

@pytest.mark.parametrize("fps", [30.0, 47.0, 240.0])
def test_resampling_keeps_a_constant_velocity_rotation_exact(fps):
    omega = np.array([0.8, -1.9, 2.7])  # rad/s, about a fixed axis
    t = np.arange(121) / 120.0
    def exact(times):
        angle = np.linalg.norm(omega) * times
        axis = omega / np.linalg.norm(omega)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        return np.eye(3) + np.sin(angle)[:, None, None] * k + (1 - np.cos(angle))[:, None, None] * (k @ k)
    rot = np.stack([exact(t), np.broadcast_to(np.eye(3), (121, 3, 3))], axis=1)
    motion = RigMotion(rot, np.stack([t, 2 * t, -t], axis=1), 120.0)
    out = resample(motion, fps)
    times = np.arange(out.num_frames) / fps
    assert out.num_frames == int(np.floor(fps + 1e-9)) + 1 and out.fps == fps
    np.testing.assert_allclose(out.rotations[:, 0], exact(times), atol=1e-12)
    np.testing.assert_allclose(out.root_translation, np.stack([times, 2 * times, -times], axis=1), atol=1e-12)


def test_quaternions_round_trip():
    rng = np.random.default_rng(1)
    m = euler_to_matrix(rng.uniform(-np.pi, np.pi, (500, 3)), "XYZ")
    m[0] = np.diag([1.0, -1.0, -1.0])  # half turns, where the trace is -1
    m[1] = np.diag([-1.0, 1.0, -1.0])
    m[2] = np.diag([-1.0, -1.0, 1.0])
    np.testing.assert_allclose(quaternion_to_matrix(matrix_to_quaternion(m)), m, atol=1e-12)


def test_start_at_capture_begins_in_the_rest_pose_and_then_follows_the_clip(walk, rig):
    _, _, clip = walk
    raw = trim(resample(retarget(clip, rig), 30.0), 2.0)
    started = start_at_capture(raw, rig, ramp_s=0.5)
    assert started.num_frames == 61
    np.testing.assert_allclose(started.rotations[0], np.broadcast_to(np.eye(3), (len(rig.names), 3, 3)), atol=1e-12)
    np.testing.assert_allclose(started.root_translation[0], 0, atol=1e-12)
    # after the ramp: the clip's own local rotations below the root, the root turned to face +Z at frame 0
    np.testing.assert_allclose(started.rotations[15:, 1:], raw.rotations[15:, 1:], atol=1e-9)
    forward = (started.rotations[15:, 0] @ np.linalg.inv(raw.rotations[15:, 0]))[:, :, 2]
    np.testing.assert_allclose(np.diff(forward, axis=0), 0, atol=1e-9)  # one fixed turn
    assert abs(forward[0, 1]) < 1e-12  # about +Y
    pos = started.joint_positions(rig)
    unblended = start_at_capture(raw, rig, ramp_s=0.0).joint_positions(rig)
    assert unblended[..., 1].min() == pytest.approx(rig.rest[:, 1].min(), abs=1e-9)  # feet on the capture's floor
    # the walk goes forward (+Z) from the capture's place
    assert pos[-1, 0, 2] - pos[0, 0, 2] > 1.0


def test_clip_on_a_body_starts_in_the_capture_pose(rig):
    """A body whose vertices sit on its joints (one joint each): skinned, they follow the retargeted joints."""
    from pgc.motion.drive import SIM_FPS, clip_body_motion
    from pgc.synth.body import SynthBody

    rest = rig.rest
    body = SynthBody("joints", {}, rest, np.array([[0, 1, 2]]), rest, rig.parents, np.eye(len(rig.names)), rig.names)
    motion = clip_body_motion(CMU / "02_04.amc", body, seconds=1.0)
    assert motion.fps == SIM_FPS == 30.0 and motion.num_frames == 31 and motion.name == "02_04"
    np.testing.assert_allclose(motion.vertices[0], rest, atol=1e-6)
    clip = read_amc_clip(CMU / "02_04.amc")
    joints = keep_arms_clear(start_at_capture(trim(resample(retarget(clip, rig), 30.0), 1.0), rig), rig
                             ).joint_positions(rig)
    np.testing.assert_allclose(motion.vertices, joints, atol=1e-5)  # float32 vertices
    assert np.abs(joints[-1] - rest).max() > 0.1  # it moves


def test_an_in_place_walk_keeps_its_root_over_the_capture_position_and_its_pose(rig):
    """In place: the root's horizontal travel is gone, its height and every joint's place relative to the root
    are the walk's own (the walk itself travels more than a metre in two seconds)."""
    from pgc.motion.drive import ClipOptions, clip_body_motion
    from pgc.synth.body import SynthBody

    rest = rig.rest
    body = SynthBody("joints", {}, rest, np.array([[0, 1, 2]]), rest, rig.parents, np.eye(len(rig.names)), rig.names)
    walking = clip_body_motion(CMU / "02_01.amc", body, seconds=2.0).vertices
    held = clip_body_motion(CMU / "02_01.amc", body, ClipOptions(in_place=True), seconds=2.0).vertices
    assert np.abs(walking[-1, 0, [0, 2]] - walking[0, 0, [0, 2]]).max() > 1.0
    np.testing.assert_allclose(held[:, 0, [0, 2]], held[:1, 0, [0, 2]].repeat(len(held), 0), atol=1e-6)
    np.testing.assert_allclose(held[:, 0, 1], walking[:, 0, 1], atol=1e-6)
    np.testing.assert_allclose(held - held[:, :1], walking - walking[:, :1], atol=1e-5)


def hanging_arm_angles(motion: RigMotion, rig: Rig) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per side: the upper arm's angle (degrees, outward positive) from the chest's down axis seen from the front,
    and whether it hangs (points down, not across the body), per frame."""
    from pgc.motion.clip import forward_kinematics

    rot, pos = forward_kinematics(np.asarray(rig.parents), rig.offsets(), motion.rotations, motion.root_translation)
    chest = rig.names.index("Spine1")
    out = {}
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        d = np.einsum("tba,tb->ta", rot[:, chest],
                      pos[:, rig.names.index(f"{side}ForeArm")] - pos[:, rig.names.index(f"{side}Arm")])
        angle = np.degrees(np.arctan2(sign * d[:, 0], -d[:, 1]))
        out[side] = angle, (d[:, 1] < 0) & (angle > -90)
    return out


@pytest.mark.parametrize("name", ["02_01", "02_05"])
def test_hanging_arms_are_kept_clear_of_the_chest(name, rig):
    """No hanging upper arm comes closer than ARM_SPACE_DEG to the chest's down axis; arms already farther out,
    and every joint but the shoulders, keep their rotations."""
    before = start_at_capture(resample(retarget(read_amc_clip(CMU / f"{name}.amc"), rig), 30.0), rig)
    after = keep_arms_clear(before, rig)
    shoulders = [rig.names.index("LeftArm"), rig.names.index("RightArm")]
    others = [j for j in range(len(rig.names)) if j not in shoulders]
    np.testing.assert_array_equal(after.rotations[:, others], before.rotations[:, others])
    old, new = hanging_arm_angles(before, rig), hanging_arm_angles(after, rig)
    moved = 0
    for side in ("Left", "Right"):
        angle, hanging = new[side]
        assert angle[hanging].min() >= ARM_SPACE_DEG - 1e-9
        clear = old[side][1] & (old[side][0] >= ARM_SPACE_DEG)
        np.testing.assert_allclose(angle[clear], old[side][0][clear], atol=1e-9)
        moved += int(np.sum(old[side][1] & ~clear))
    assert moved > 0


# bad input: one clear error each ---------------------------------------------------------------------

def _edit(tmp_path: Path, name: str, edit) -> Path:
    text = (CMU / name).read_bytes().decode()
    (tmp_path / name).write_text(edit(text))
    if name.endswith(".amc"):
        (tmp_path / "02.asf").write_bytes((CMU / "02.asf").read_bytes())
    return tmp_path / name


@pytest.mark.parametrize("edit,match", [
    (lambda s: s.replace("angle deg", "angle grad"), r"02\.asf: :units angle 'grad': expected 'deg' or 'rad'"),
    (lambda s: s.replace("length 0.45", "length 0.0045"), r"02\.asf: the :units length field: the rest skeleton "
                                                          r"spans 1.*m, not a person's .*unexpected units"),
    (lambda s: s.replace("  length 0.45\r\n", "\r\n"), r"02\.asf: :units must give 'length' and 'angle'"),
    (lambda s: s[:s.index("name rtibia")], r"02\.asf: bone block from line \d+ has no 'end': .*truncated"),
    (lambda s: s.replace("axis 0 0 20  XYZ", "axis 0 0 20  XXY"), r"bone 'lfemur' axis: unsupported rotation "
                                                                  r"order 'XXY'"),
    (lambda s: s.replace("lhumerus lradius", "lhumerus lradiux"), r":hierarchy names bones the :bonedata "
                                                                  r"lacks: lradiux"),
    (lambda s: s.replace("lradius lwrist", "lradius lwrist lhumerus"), r":hierarchy must reach every bone once "
                                                                       r"from 'root' \(a bone has two parents or a "
                                                                       r"cycle\)"),
])
def test_bad_asf(tmp_path, edit, match):
    path = _edit(tmp_path, "02.asf", edit)
    with pytest.raises(PGCDataError, match=match):
        read_asf(path)


@pytest.mark.parametrize("edit,match", [
    (lambda s: s.replace("rtibia 11.5302", "rtibiaa 11.5302"), r"02_01\.amc: line 27: bone 'rtibiaa' does not "
                                                                r"match the skeleton 02\.asf.*--skeleton"),
    (lambda s: s.replace("rtibia 11.5302", "rtibia 11.5302 2.0"), r"line 27: bone 'rtibia' has 2 values but "
                                                                   r"its skeleton 02\.asf gives it 1 degrees"),
    (lambda s: s.replace("rtibia 11.5302", "rtibia nan"), r"line 27: frame 1, bone 'rtibia': NaN or infinite "
                                                           r"angles"),
    (lambda s: s[:s.index("\n1\r\n") + 1], r"02_01\.amc: the clip has zero frames"),
    (lambda s: s[:s.rindex("lfemur")], r"frame 343 \(line \d+\) lists no values for lfemur, ltibia, lfoot, "
                                       r"ltoes: the file is truncated"),
    (lambda s: s.replace("\n3\r\n", "\n4\r\n", 1), r"frame number 4, expected 3"),
    (lambda s: s.replace("rtibia 11.5302", "rtibia 11.53o2"), r"line 27 \(rtibia\): expected numbers, got "
                                                               r"'11.53o2'; the file is garbled"),
])
def test_bad_amc(tmp_path, edit, match):
    path = _edit(tmp_path, "02_01.amc", edit)
    with pytest.raises(PGCDataError, match=match):
        read_amc_clip(path)


def _nan_in_last_frame(text: str) -> str:
    head, last = text.rstrip("\n").rsplit("\n", 1)
    return head + "\nnan " + last.split(" ", 1)[1] + "\n"


@pytest.mark.parametrize("edit,match", [
    (lambda s: s.replace("Zrotation Yrotation Xrotation", "Zrotation Yrotation Yrotation", 2),
     r"joint 'root': unsupported rotation order 'Zrotation Yrotation Yrotation'"),
    (lambda s: s.replace("Zrotation Yrotation Xrotation", "Zrotation Wrotation Xrotation", 1),
     r"joint 'root': unknown channel 'Wrotation'"),
    (lambda s: s[:s.index("JOINT lfemur")], r"02_03\.bvh: no MOTION section"),
    (lambda s: s[:s.index("MOTION")] + "MOTION\nFrames: 0\nFrame Time: 0.0083\n", r"Frames: 0: the clip has "
                                                                                    r"zero frames"),
    (lambda s: s[:s.rindex("\n", 0, len(s) - 1)], r"'Frames: 173' but 172 lines of values follow"),
    (lambda s: _nan_in_last_frame(s), r"frame 172 \(0-based\): NaN or infinite channel values"),
    (lambda s: s.replace("OFFSET 0 0 0", "OFFSET 0 0 O", 1), r"OFFSET of 'root': expected a number, found 'O'"),
])
def test_bad_bvh(tmp_path, edit, match):
    path = _edit(tmp_path, "02_03.bvh", edit)
    with pytest.raises(PGCDataError, match=match):
        read_bvh(path)


def test_bvh_nesting_is_bounded(tmp_path):
    depth = 2000
    text = ("HIERARCHY\nROOT j0\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n"
            + "".join(f"JOINT j{k}\n{{\n OFFSET 0 0.1 0\n CHANNELS 1 Xrotation\n" for k in range(1, depth))
            + "}\n" * depth + "MOTION\nFrames: 1\nFrame Time: 0.01\n" + "0 " * (depth + 2) + "\n")
    (tmp_path / "deep.bvh").write_text(text)
    with pytest.raises(PGCDataError, match=r"deep\.bvh: line \d+: joints nest deeper than 256 levels"):
        read_bvh(tmp_path / "deep.bvh")


def test_bvh_in_unexpected_units(tmp_path):
    with pytest.raises(PGCDataError, match=r"02_03\.bvh: OFFSET: at 1\.0 m per unit the rest skeleton spans "
                                           r"1.*m.*--clip-unit"):
        read_bvh(CMU / "02_03.bvh", unit_m=1.0)


def test_clip_options_must_fit_the_clip():
    from pgc.motion.drive import ClipOptions

    with pytest.raises(PGCDataError, match="--skeleton is for .amc clips"):
        load_clip(CMU / "02_03.bvh", ClipOptions(skeleton=CMU / "02.asf"))
    with pytest.raises(PGCDataError, match="a length unit is for BVH files"):
        load_clip(CMU / "02_01.amc", ClipOptions(unit_m=0.01))
    with pytest.raises(PGCDataError, match=r"clip frame rate nan"):
        load_clip(CMU / "02_01.amc", ClipOptions(fps=float("nan")))
    with pytest.raises(PGCDataError, match="clip file not found"):
        load_clip(CMU / "99_01.amc")


def test_a_binary_file_is_refused(tmp_path):
    (tmp_path / "02.asf").write_bytes(b"\x00\x01\x02junk" * 10)
    with pytest.raises(PGCDataError, match=r"02\.asf: binary data"):
        read_asf(tmp_path / "02.asf")
