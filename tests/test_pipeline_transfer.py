"""Embedding points on a rest surface and carrying them along a deformation."""

import numpy as np

from pgc.pipeline.transfer import embed, place
from pgc.testing.cloth_scenes import grid_cloth


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
