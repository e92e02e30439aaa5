"""The synthetic capture's body (a body_model body with a phenotype per seed), its skinning and motions; the
garments fitted to it."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.motion.rotations import axis_angle_to_matrix
from pgc.roles.body_model import global_transforms
from pgc.synth.body import PLAUSIBLE_PHENOTYPE, draw_phenotype, make_body
from pgc.synth.garments import RESTING_TOP_GAP, boundary_loops, make_garment
from pgc.synth.motions import MOTIONS, arm_keyframe, axis_angle, make_motion, motion_rotations

EDGE = 0.04  # coarse garments keep these tests fast; the construction is the same at every resolution
SEEDS = (0, 1, 2)


@pytest.fixture(scope="module")
def body(default_body_model):
    return make_body(default_body_model)


def _edge_counts(faces: np.ndarray) -> np.ndarray:
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)[1]


def test_body_is_the_body_models_closed_oriented_adult(body, default_body_model):
    assert np.all(_edge_counts(body.faces) == 2)  # closed 2-manifold
    v = body.vertices[body.faces]
    volume = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6
    assert 0.05 < volume < 0.1  # m^3, an adult, outward orientation (positive)
    assert abs(body.vertices[:, 1].min()) < 1e-9 and 1.6 < body.height < 2.0
    state = default_body_model.forward()
    np.testing.assert_allclose(body.vertices, state.vertices)
    np.testing.assert_allclose(body.joints, state.joints)
    assert body.joint_names == default_body_model.joint_names and body.model == "AnnyBody"
    assert np.all(body.weights >= -1e-9)
    np.testing.assert_allclose(body.weights.sum(axis=1), 1.0, atol=1e-9)


def test_each_seed_draws_a_plausible_phenotype_and_a_different_body(default_body_model):
    heights, shapes = [], []
    for seed in SEEDS:
        shape = draw_phenotype(default_body_model, seed)
        assert shape == draw_phenotype(default_body_model, seed)  # deterministic
        for name, (lo, hi) in PLAUSIBLE_PHENOTYPE.items():
            assert lo <= shape[name] <= hi
        b = make_body(default_body_model, shape)
        assert b.phenotype == shape
        heights.append(b.height)
        shapes.append(b.vertices)
    assert 1.45 < min(heights) and max(heights) < 2.1, heights
    assert len({round(h, 3) for h in heights}) == len(SEEDS), heights
    for a in range(len(SEEDS)):
        for b in range(a + 1, len(SEEDS)):
            assert np.abs(shapes[a] - shapes[b]).max() > 0.02  # metres: the bodies differ


def test_field_is_the_signed_distance_to_the_surface(body):
    from pgc.arrays import array_ops
    from pgc.sim.collision import vertex_normals
    from pgc.sim.xpbd import closest_contact

    rng = np.random.default_rng(3)
    near = body.vertices[rng.integers(0, len(body.vertices), 300)] + rng.normal(0, 0.03, (300, 3))
    far = rng.uniform(body.vertices.min(0) - 0.4, body.vertices.max(0) + 0.4, (100, 3))
    points = np.concatenate([near, far])
    every = np.broadcast_to(body.faces, (len(points),) + body.faces.shape)  # brute force: every triangle
    contact = closest_contact(array_ops("numpy"), points, body.vertices, vertex_normals(body.vertices, body.faces),
                              every)
    truth = np.where(contact.signed < 0, -1.0, 1.0) * np.linalg.norm(points - contact.point, axis=1)
    d = body.field(points)
    assert np.all(np.abs(d) >= np.abs(truth) - 1e-9)  # the closest of some triangles: never nearer
    near_surface = np.abs(truth) < 0.05
    err = np.abs(d - truth)[near_surface]
    assert err.max() < 5e-3 and err.mean() < 2e-4, (err.max(), err.mean())  # metres (measured 3.7 mm, 0.04 mm)
    assert np.all(np.sign(d[np.abs(truth) > 0.01]) == np.sign(truth[np.abs(truth) > 0.01]))


def test_identity_pose_is_rest_and_root_rotation_is_rigid(body):
    J = len(body.joint_names)
    np.testing.assert_allclose(body.pose(np.broadcast_to(np.eye(3), (J, 3, 3))), body.vertices, atol=1e-12)
    rot = np.broadcast_to(np.eye(3), (J, 3, 3)).copy()
    R = axis_angle_to_matrix(np.array([0.3, -0.5, 0.2]))
    rot[0] = R
    pivot = body.joints[0]
    np.testing.assert_allclose(body.pose(rot, np.array([0.1, 0, 0])), (body.vertices - pivot) @ R.T + pivot
                               + [0.1, 0, 0], atol=1e-10)


def test_axis_angle_inverts_axis_angle_to_matrix():
    rng = np.random.default_rng(0)
    for aa in rng.normal(0, 1.0, (20, 3)):
        aa = aa / max(1.0, np.linalg.norm(aa) / 3.0)  # angles below pi
        np.testing.assert_allclose(axis_angle(axis_angle_to_matrix(aa)), aa, atol=1e-9)
    np.testing.assert_allclose(axis_angle(np.eye(3)), 0.0)


@pytest.mark.parametrize("upper, fore", [((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)), ((0.15, 0.0, 1.0), (0.15, 0.15, 0.98)),
                                         ((0.45, 0.89, 0.05), (-0.42, 0.9, 0.05))])
def test_arm_keyframes_point_the_bones_where_asked(body, upper, fore):
    J = len(body.joint_names)
    rot = np.broadcast_to(np.eye(3), (J, 3, 3)).copy()
    for name, aa in arm_keyframe(body, upper, fore).items():
        rot[body.joint_names.index(name)] = axis_angle_to_matrix(aa)
    T = global_transforms(body.joints, body.parents, rot)
    posed = np.einsum("jab,jb->ja", T[:, :3, :3], body.joints) + T[:, :3, 3]
    for word, sign in (("Left", 1.0), ("Right", -1.0)):
        s, e, w = (posed[body.joint_names.index(f"{word}{j}")] for j in ("Arm", "ForeArm", "Hand"))
        m = np.array([sign, 1.0, 1.0])
        np.testing.assert_allclose((e - s) / np.linalg.norm(e - s), m * upper / np.linalg.norm(upper), atol=1e-9)
        np.testing.assert_allclose((w - e) / np.linalg.norm(w - e), m * fore / np.linalg.norm(fore), atol=1e-9)


@pytest.mark.parametrize("name", MOTIONS)
def test_motion_starts_in_the_capture_pose_and_skins_without_tearing(body, name):
    motion = make_motion(body, name)
    assert motion.fps == 30.0 and motion.num_frames >= 60
    np.testing.assert_allclose(motion.vertices[0], body.vertices, atol=1e-5)
    e = body.mesh().edges()
    rest = np.linalg.norm(body.vertices[e[:, 0]] - body.vertices[e[:, 1]], axis=1)
    length = np.linalg.norm(motion.vertices[:, e[:, 0]] - motion.vertices[:, e[:, 1]], axis=2)
    ratio = length / rest
    assert ratio.max() < 3.5 and ratio.min() > 0.1, (ratio.min(), ratio.max())
    assert np.abs(np.diff(motion.vertices, axis=0)).max() < 0.1  # smooth: under 3 m/s (walk: toes 2.8 m/s)
    assert np.abs(motion.vertices[-1] - motion.vertices[0]).max() > 0.1  # the pose changes


def test_the_papers_test_motions_end_in_their_poses(body):
    def hands(name):
        posed = body.pose(motion_rotations(name, body)[-1])
        return [posed[np.argmax(body.weights[:, body.joint_names.index(h)])] for h in ("LeftHand", "RightHand")]

    shoulder = body.joint("l_shoulder")
    for hand in hands("goalpost"):
        assert hand[1] > shoulder[1] + 0.15  # forearms up
    for hand in hands("spooky"):
        assert hand[2] > shoulder[2] + 0.35 and abs(hand[1] - shoulder[1]) < 0.2  # arms forward
    for hand in hands("arms-up"):
        assert hand[1] > body.height  # above the head


def test_bad_inputs_are_named(body, default_body_model):
    with pytest.raises(PGCDataError, match="unknown motion"):
        motion_rotations("moonwalk", body)
    with pytest.raises(PGCDataError, match="height"):
        make_body(default_body_model, {"height": 5.0})
    with pytest.raises(PGCDataError, match="unknown garment"):
        make_garment(body, "kilt")
    with pytest.raises(PGCDataError, match="no joint 'l_knee'"):
        body.joint("l_knee")


def _check_shell(body, g, fit, edge=EDGE):
    """A simulation-quality shell outside the body: its four boundaries, uniform edges, no slivers, no edge
    crossing the body, and the clearance of the fit."""
    from pgc_mitsuba.runtime import mesh_to_mitsuba, mitsuba

    from pgc.sim.collision import signed_distance

    mi = mitsuba()
    assert len(boundary_loops(g)) == 4  # hem, neck, two sleeves
    assert np.all(_edge_counts(g.faces) <= 2)  # manifold with boundary
    assert g.uv is not None and g.uv.min() >= 0 and g.uv.max() <= 1
    length = np.linalg.norm(g.vertices[g.edges()[:, 0]] - g.vertices[g.edges()[:, 1]], axis=1)
    assert length.std() / length.mean() < 0.25 and abs(length.mean() / edge - 1) < 0.15
    v = g.vertices[g.faces]
    cos = [np.einsum("ij,ij->i", v[:, (k + 1) % 3] - v[:, k], v[:, (k + 2) % 3] - v[:, k])
           / np.linalg.norm(v[:, (k + 1) % 3] - v[:, k], axis=1) / np.linalg.norm(v[:, (k + 2) % 3] - v[:, k], axis=1)
           for k in range(3)]
    assert np.degrees(np.arccos(np.clip(np.max(cos, axis=0), -1, 1))).min() > 5.0  # smallest angle
    scene = mi.load_dict({"type": "scene", "body": mesh_to_mitsuba(body.vertices, body.faces)})
    e = g.edges()
    o, d = g.vertices[e[:, 0]], g.vertices[e[:, 1]] - g.vertices[e[:, 0]]
    length = np.linalg.norm(d, axis=1)
    ray = mi.Ray3f(mi.Point3f(*[mi.Float(o[:, k]) for k in range(3)]),
                   mi.Vector3f(*[mi.Float(d[:, k] / length) for k in range(3)]))
    ray.maxt = mi.Float(length)
    assert not np.any(np.array(scene.ray_test(ray)))  # no garment edge crosses the body surface
    gap = signed_distance(g.vertices, body.vertices, body.faces, k=64)
    # measured minima over the seeds and garments: 24 mm (loose 3 cm), 2.3 mm (resting)
    assert gap.min() > (0.02 if fit == "loose" else 0.4 * RESTING_TOP_GAP), gap.min()
    return gap


@pytest.mark.parametrize("seed", SEEDS)
def test_a_loose_tee_fits_each_seeds_body(default_body_model, seed):
    b = make_body(default_body_model, draw_phenotype(default_body_model, seed))
    gap = _check_shell(b, make_garment(b, "tshirt", resolution=EDGE, fit="loose", looseness=0.03), "loose")
    assert abs(np.median(gap[gap < np.quantile(gap, 0.3)]) - 0.03) < 0.005  # the looseness where it rests


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("kind, fit", [("dress", "loose"), ("tshirt", "resting"), ("dress", "resting")])
def test_every_garment_fits_each_seeds_body(default_body_model, seed, kind, fit):
    b = make_body(default_body_model, draw_phenotype(default_body_model, seed))
    edge = EDGE if fit == "loose" else 0.02  # a 4 cm chord over an arm sags through a 5 mm clearance
    g = make_garment(b, kind, resolution=edge, fit=fit, looseness=0.03 if fit == "loose" else 0.012)
    gap = _check_shell(b, g, fit, edge)
    if fit == "resting":  # it rests on the shoulders
        top = g.vertices[:, 1] >= np.quantile(g.vertices[:, 1], 0.85)
        assert abs(np.median(gap[top]) - RESTING_TOP_GAP) < 0.002
