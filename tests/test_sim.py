"""Backend-independent simulator pieces: topology, masses, colouring, closest points, schedule, sag-free."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.sim.collision import candidate_corners, signed_distance, vertex_normals
from pgc.arrays import array_ops
from pgc.sim.xpbd import closest_barycentric
from pgc.sim.model import BEND, STRETCH, bending_pairs, build_cloth_model, vertex_masses
from pgc.sim.sagfree import hem_sag, sag, shape_error, solve_sag_free
from pgc.testing.cloth_scenes import grid_cloth, skirt, uv_sphere
from pgc.sim.schedule import body_schedule
from pgc.types import BodyMotion, Mesh


def test_bending_pairs_are_the_vertices_opposite_interior_edges():
    two = np.array([[0, 1, 2], [2, 1, 3]])  # shared edge 1-2, opposite vertices 0 and 3
    np.testing.assert_array_equal(bending_pairs(two), [[0, 3]])
    faces = grid_cloth(5).faces
    expected = set()
    for a in range(len(faces)):
        for b in range(a + 1, len(faces)):
            shared = set(faces[a]) & set(faces[b])
            if len(shared) == 2:
                pair = (set(faces[a]) - shared).pop(), (set(faces[b]) - shared).pop()
                expected.add((min(pair), max(pair)))
    assert {tuple(p) for p in bending_pairs(faces).tolist()} == expected  # unique pairs, no duplicates


def test_masses_sum_to_density_times_area():
    cloth = grid_cloth(7, size=0.8)
    m = vertex_masses(cloth.vertices, cloth.faces, 0.2)
    assert m.sum() == pytest.approx(0.2 * 0.64, rel=1e-12)
    faces = np.array([[0, 1, 2], [0, 0, 3]])  # vertex 3 is only on a degenerate triangle
    m = vertex_masses(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]]), faces, 1.0)
    assert np.all(m > 0) and m[3] == pytest.approx(1e-3 * m.mean() / (1 + 0), rel=0.5)


@pytest.mark.parametrize("mesh", [grid_cloth(9), skirt(0.2, 0.4, 1.0, 6, 16)])
def test_colouring_is_a_proper_partition(mesh):
    model = build_cloth_model(mesh, 0.15, 5e3, 5.0)
    seen = np.concatenate(model.colours)
    assert np.array_equal(np.sort(seen), np.arange(len(model.ci)))
    for idx in model.colours:
        verts = np.concatenate([model.ci[idx], model.cj[idx]])
        assert len(np.unique(verts)) == len(verts)  # no shared vertex inside a colour
    assert set(np.unique(model.kind)) == {STRETCH, BEND}
    np.testing.assert_allclose(model.rest, np.linalg.norm(mesh.vertices[model.ci] - mesh.vertices[model.cj], axis=1))


def test_closest_point_matches_dense_sampling_and_degenerate_triangles_are_finite():
    rng = np.random.default_rng(0)
    tri = rng.normal(size=(3, 3))
    uv = rng.random((20000, 2))
    uv = np.where(uv.sum(1, keepdims=True) > 1, 1 - uv, uv)
    samples = tri[0] + uv[:, :1] * (tri[1] - tri[0]) + uv[:, 1:] * (tri[2] - tri[0])
    p = rng.normal(size=(200, 3)) * 2
    u, v, w = closest_barycentric(array_ops("numpy"), p, tri[0], tri[1], tri[2])
    q = u[:, None] * tri[0] + v[:, None] * tri[1] + w[:, None] * tri[2]
    brute = np.linalg.norm(p[:, None] - samples[None], axis=2).min(1)
    d = np.linalg.norm(p - q, axis=1)
    assert np.all(d <= brute + 1e-12) and np.all(brute - d < 0.02)
    assert np.all((np.stack([u, v, w]) >= -1e-12) & (np.stack([u, v, w]) <= 1 + 1e-12))
    for a, b, c in ([0, 0, 0], [0, 0, 0], [0, 0, 0]), ([0, 0, 0], [1, 0, 0], [2, 0, 0]), ([0, 0, 0], [1, 0, 0], [1, 0, 0]):
        out = closest_barycentric(array_ops("numpy"), p, np.array(a, float), np.array(b, float), np.array(c, float))
        assert all(np.all(np.isfinite(o)) for o in out)


def test_signed_distance_to_a_sphere():
    sphere = uv_sphere(0.3, rings=32, segments=64)
    rng = np.random.default_rng(1)
    dirs = rng.normal(size=(300, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    r = rng.uniform(0.2, 0.4, size=(300, 1))
    sd = signed_distance(dirs * r, sphere.vertices, sphere.faces)
    np.testing.assert_allclose(sd, r[:, 0] - 0.3, atol=3e-3)  # tessellation error of 32 x 64 rings
    n = vertex_normals(sphere.vertices, sphere.faces)
    np.testing.assert_allclose((n * sphere.vertices / 0.3).sum(1), 1.0, atol=1e-2)
    assert candidate_corners(dirs, sphere.vertices, sphere.faces, 8).shape == (300, 8, 3)


def test_body_schedule_settles_then_blends_in():
    body = uv_sphere(0.3, rings=6, segments=8)
    motion = BodyMotion(np.stack([body.vertices + [0.1, 0, 0], body.vertices + [0.2, 0, 0]]), body.faces)
    s = body_schedule(motion, settle_frames=3, blend_frames=4, capture=body.vertices)
    assert s.vertices.shape[0] == 1 + 3 + 4 + 2 and s.first_motion == 8
    np.testing.assert_allclose(s.vertices[:4], np.broadcast_to(body.vertices, (4,) + body.vertices.shape))
    shift = s.vertices[4:8, 0, 0] - body.vertices[0, 0]
    assert np.all(np.diff(shift) > 0) and shift[-1] == pytest.approx(0.1)
    same = body_schedule(motion, 2, 4)  # capture = motion frame 0: no blend frames
    assert same.first_motion == 3


class _Spring:
    """Equilibrium of a chain hanging from vertex 0 with linear springs (exact statics, for the driver)."""

    def __init__(self, k: float, weight: float) -> None:
        self.k, self.weight = k, weight

    def __call__(self, model):
        # tension in segment s carries the weight of the vertices below it: (n - 1 - s) * weight
        n = model.num_vertices
        tension = (n - 1 - np.arange(n - 1)) * self.weight
        lengths = model.rest[: n - 1] + tension / self.k
        y = -np.concatenate([[0.0], np.cumsum(lengths)])
        return np.stack([np.zeros(n), y, np.zeros(n)], 1)


def test_sag_free_rest_lengths_reproduce_the_target_under_load():
    n = 6
    chain = Mesh(np.stack([np.zeros(n), -0.1 * np.arange(n), np.zeros(n)], 1),
                 np.array([[i, i + 1, i + 1] for i in range(n - 1)]), name="chain")
    model = build_cloth_model(chain, 0.1, 100.0, 0.0)
    model = model.with_rest(np.full(len(model.ci), 0.1))  # edges in chain order
    order = np.argsort(model.ci)
    model = model.__class__(**{**model.__dict__, "ci": model.ci[order], "cj": model.cj[order]})
    model, history = solve_sag_free(model, _Spring(k=100.0, weight=0.5), iterations=6)
    assert history[0]["sag_max"] > 0.05
    assert history[-1]["sag_max"] < 1e-3 * history[0]["sag_max"]
    assert np.all(model.rest < 0.1)  # pre-shortened


def test_sag_measures_split_a_rigid_drop_from_deformation():
    target = grid_cloth(5, 0.4, 1.0, vertical=True).vertices  # rows 0.1 m apart, the hem at y = 0.6
    dropped = target - [0.0, 0.03, 0.0]
    assert sag(dropped, target) == pytest.approx((0.03, 0.03))
    assert shape_error(dropped, target) == pytest.approx(0.0, abs=1e-15)  # a rigid drop: no deformation
    assert hem_sag(dropped, target) == pytest.approx(0.03)
    stretched = target.copy()
    stretched[:, 1] = 1.0 + 1.1 * (target[:, 1] - 1.0)  # 10 % longer, hanging from y = 1
    assert hem_sag(stretched, target) == pytest.approx(0.04)  # only the hem row (0.4 m below the top) counts
    assert shape_error(stretched, target) > 0.0
