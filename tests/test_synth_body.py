"""The synthetic body, its skinning and motions; the garments around it."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.synth.body import BodyShape, make_body
from pgc.synth.garments import RESTING_TOP_GAP, boundary_loops, make_garment
from pgc.synth.motions import MOTIONS, make_motion, motion_rotations
from pgc.motion.rotations import axis_angle_to_matrix
from pgc.synth.skeleton import JOINTS, joint_index, rotation_between

EDGE = 0.04  # coarse meshes keep these tests fast; the construction is the same at every resolution


@pytest.fixture(scope="module")
def body():
    return make_body(edge_length=EDGE)


def _edge_counts(faces: np.ndarray) -> np.ndarray:
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)[1]


def test_body_is_closed_oriented_and_human_sized(body):
    assert np.all(_edge_counts(body.faces) == 2)  # closed 2-manifold
    v = body.vertices[body.faces]
    volume = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6
    assert 0.045 < volume < 0.09  # m^3, an adult of about 60-80 kg, outward orientation (positive)
    lo, hi = body.vertices.min(axis=0), body.vertices.max(axis=0)
    assert abs(hi[1] - 1.70) < 0.03 and lo[1] < 0.03
    assert len(JOINTS) >= 20 and body.joints.shape == (len(JOINTS), 3)


def test_skinning_weights_are_a_partition_of_unity(body):
    assert np.all(body.weights >= 0)
    np.testing.assert_allclose(body.weights.sum(axis=1), 1.0, atol=1e-12)
    # the hands follow the wrists, the feet the ankles
    hand = np.argmax(body.vertices[:, 0])
    assert body.weights[hand, joint_index("l_wrist")] > 0.7


def test_identity_pose_is_rest_and_root_rotation_is_rigid(body):
    rest = body.pose(np.broadcast_to(np.eye(3), (len(JOINTS), 3, 3)))
    np.testing.assert_allclose(rest, body.vertices, atol=1e-12)
    rot = np.broadcast_to(np.eye(3), (len(JOINTS), 3, 3)).copy()
    R = axis_angle_to_matrix(np.array([0.3, -0.5, 0.2]))
    rot[joint_index("pelvis")] = R
    posed = body.pose(rot)
    pivot = body.joints[joint_index("pelvis")]
    np.testing.assert_allclose(posed, (body.vertices - pivot) @ R.T + pivot, atol=1e-10)


def test_rotation_helpers():
    a, b = np.array([1.0, -1, 0]), np.array([0.0, 0, 1])
    R = axis_angle_to_matrix(rotation_between(a, b))
    np.testing.assert_allclose(R @ (a / np.linalg.norm(a)), b, atol=1e-12)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    R = axis_angle_to_matrix(rotation_between(b, -b))  # antiparallel: a half turn, still a rotation
    np.testing.assert_allclose(R @ b, -b, atol=1e-12)
    np.testing.assert_allclose(axis_angle_to_matrix(np.zeros(3)), np.eye(3))


@pytest.mark.parametrize("name", MOTIONS)
def test_motion_starts_in_a_pose_and_skins_without_tearing(body, name):
    motion = make_motion(body, name)
    assert motion.fps == 30.0 and motion.num_frames >= 60
    np.testing.assert_allclose(motion.vertices[0], body.vertices, atol=1e-5)
    e = body.mesh().edges()
    rest = np.linalg.norm(body.vertices[e[:, 0]] - body.vertices[e[:, 1]], axis=1)
    length = np.linalg.norm(motion.vertices[:, e[:, 0]] - motion.vertices[:, e[:, 1]], axis=2)
    ratio = length / rest
    assert ratio.max() < 3.5 and ratio.min() > 0.1, (ratio.min(), ratio.max())
    # smooth in time: no vertex jumps more than 8 cm between frames at 30 fps
    assert np.abs(np.diff(motion.vertices, axis=0)).max() < 0.08
    # the pose actually changes
    assert np.abs(motion.vertices[-1] - motion.vertices[0]).max() > 0.1


def test_goalpost_raises_the_forearms(body):
    rot = motion_rotations("goalpost")[-1]
    wrist = body.pose(rot)[np.argmax(body.weights[:, joint_index("l_wrist")])]
    assert wrist[1] > body.joints[joint_index("l_shoulder"), 1] + 0.15  # hands above the shoulders


def test_bad_inputs_are_named():
    with pytest.raises(PGCDataError, match="unknown motion"):
        motion_rotations("moonwalk")
    with pytest.raises(PGCDataError, match="height"):
        BodyShape(height=5.0)
    with pytest.raises(PGCDataError, match="unknown garment"):
        make_garment(make_body(edge_length=EDGE), "kilt")


@pytest.mark.parametrize("kind, fit", [("tshirt", "loose"), ("dress", "loose"), ("tshirt", "resting"),
                                       ("dress", "resting")])
def test_garment_shell_does_not_intersect_the_body(body, kind, fit):
    from pgc_mitsuba.runtime import mesh_to_mitsuba, mitsuba

    mi = mitsuba()
    g = make_garment(body, kind, resolution=EDGE, fit=fit, looseness=0.03 if fit == "loose" else 0.012)
    assert len(boundary_loops(g)) == 4  # hem, neck, two sleeves
    counts = _edge_counts(g.faces)
    assert np.all(counts <= 2)  # manifold with boundary
    assert g.uv is not None and g.uv.min() >= 0 and g.uv.max() <= 1
    # simulation quality: roughly uniform edges, no slivers
    length = np.linalg.norm(g.vertices[g.edges()[:, 0]] - g.vertices[g.edges()[:, 1]], axis=1)
    assert length.std() / length.mean() < 0.25 and abs(length.mean() / EDGE - 1) < 0.15
    v = g.vertices[g.faces]
    cos = [np.einsum("ij,ij->i", v[:, (k + 1) % 3] - v[:, k], v[:, (k + 2) % 3] - v[:, k])
           / np.linalg.norm(v[:, (k + 1) % 3] - v[:, k], axis=1) / np.linalg.norm(v[:, (k + 2) % 3] - v[:, k], axis=1)
           for k in range(3)]
    assert np.degrees(np.arccos(np.clip(np.max(cos, axis=0), -1, 1))).min() > 5.0  # smallest angle
    scene = mi.load_dict({"type": "scene", "body": mesh_to_mitsuba(body.vertices, body.faces)})
    # no garment edge crosses the body surface ...
    e = g.edges()
    o, d = g.vertices[e[:, 0]], g.vertices[e[:, 1]] - g.vertices[e[:, 0]]
    length = np.linalg.norm(d, axis=1)
    ray = mi.Ray3f(mi.Point3f(*[mi.Float(o[:, k]) for k in range(3)]),
                   mi.Vector3f(*[mi.Float(d[:, k] / length) for k in range(3)]))
    ray.maxt = mi.Float(length)
    assert not np.any(np.array(scene.ray_test(ray)))
    # ... and the (connected) garment is outside: a ray from its highest vertex upwards leaves the body
    # an even number of times
    top = g.vertices[np.argmax(g.vertices[:, 1])]
    hits, origin = 0, mi.Point3f(*(float(x) for x in top))
    for _ in range(10):
        si = scene.ray_intersect(mi.Ray3f(origin, mi.Vector3f(0, 1, 0)))
        if not bool(si.is_valid()[0]):
            break
        hits += 1
        origin = si.p + mi.Vector3f(0, 1e-4, 0)
    assert hits % 2 == 0
    # clearance: exact distance of every garment vertex to the body surface
    o3d = pytest.importorskip("open3d")
    rc = o3d.t.geometry.RaycastingScene()
    rc.add_triangles(o3d.core.Tensor(body.vertices.astype(np.float32)), o3d.core.Tensor(body.faces.astype(np.uint32)))
    dist = rc.compute_distance(o3d.core.Tensor(g.vertices.astype(np.float32))).numpy()
    assert dist.min() > (0.01 if fit == "loose" else 0.5 * RESTING_TOP_GAP), dist.min()
