"""Embedding points on a rest surface and carrying them along a deformation."""

import numpy as np

from pgc.pipeline.transfer import CLEARANCE_M, clear_of_body, embed, place, rest_clearance
from pgc.sim.collision import signed_distance
from pgc.testing.cloth_scenes import grid_cloth, uv_sphere


def test_embedding_reproduces_rest_points_and_follows_rigid_motion():
    mesh = grid_cloth(8, size=1.0)
    rng = np.random.default_rng(0)
    # points near the surface: on it plus a small normal offset
    face = rng.integers(0, len(mesh.faces), 200)
    bary = rng.dirichlet(np.ones(3), 200)
    normal = mesh.face_normals()[face]
    pts = np.einsum("nk,nkc->nc", bary, mesh.vertices[mesh.faces[face]]) + 0.01 * normal
    e = embed(pts, mesh)
    np.testing.assert_allclose(place(e, mesh, mesh.vertices), pts, atol=1e-9)
    np.testing.assert_allclose(e.offset, 0.01, atol=1e-9)
    # a rigid motion of the surface moves the points rigidly
    angle = 0.7
    rot = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    moved = mesh.vertices @ rot.T + [0.3, -0.2, 1.0]
    np.testing.assert_allclose(place(e, mesh, moved), pts @ rot.T + [0.3, -0.2, 1.0], atol=1e-9)


def test_carried_points_keep_the_clearance_they_rested_with():
    """On a sphere: points sunk into the body come back out along its normal to the clearance they rested with (at
    most 2 mm; one that rested 3 mm inside comes back to 3 mm inside); points already clear, or beyond reach, stay."""
    body = uv_sphere(0.3, rings=48, segments=96)
    rng = np.random.default_rng(1)
    direction = rng.normal(size=(5, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    rest = np.array([0.005, 0.001, 0.005, -0.003, 0.005])  # signed distance at rest, m
    now = np.array([-0.01, 0.0015, 0.02, -0.006, 0.05])  # after being carried along
    at = lambda d: direction * (0.3 + d)[:, None]  # noqa: E731 (radial distance, not yet the polygon's)
    clearance = rest_clearance(at(rest), body)
    np.testing.assert_allclose(clearance, np.minimum(signed_distance(at(rest), body.vertices, body.faces), CLEARANCE_M))
    assert clearance[3] < 0 < clearance[1] < CLEARANCE_M and (clearance[[0, 2, 4]] == CLEARANCE_M).all()
    moved = clear_of_body(at(now), body.vertices, body.faces, clearance)
    after = signed_distance(moved, body.vertices, body.faces)
    np.testing.assert_allclose(after[[0, 3]], clearance[[0, 3]], atol=1e-6)  # pushed out to their clearance
    np.testing.assert_array_equal(moved[[1, 2, 4]], at(now)[[1, 2, 4]])  # clear already, or out of reach
    radial = moved[[0, 3]] / np.linalg.norm(moved[[0, 3]], axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", radial, direction[[0, 3]]) > 1 - 1e-4)  # along the normal
