"""Data model: camera maths against hand-computed values, validation errors that name the field."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import look_at_camera, seamed_cube
from pgc.errors import PGCDataError
from pgc.types import Camera, Capture, GaussianSet, Mesh, View


def test_camera_projection_hand_computed():
    # camera at (0, 0, -2) looking along +Z (OpenCV axes = world axes, y down): t = (0, 0, 2)
    K = np.array([[100.0, 0, 32], [0, 100.0, 24], [0, 0, 1]])
    cam = Camera(K=K, R=np.eye(3), t=[0, 0, 2], width=64, height=48)
    np.testing.assert_allclose(cam.center, [0, 0, -2])
    uv, z = cam.project(np.array([[0.0, 0, 0], [0.2, -0.1, 0]]))
    np.testing.assert_allclose(uv, [[32, 24], [42, 19]])  # 32 + 100 * 0.2 / 2, 24 - 100 * 0.1 / 2
    np.testing.assert_allclose(z, [2, 2])
    origins, dirs = cam.rays()
    np.testing.assert_allclose(origins[0, 0], [0, 0, -2])
    # pixel (row 24, col 32) has its centre at (32.5, 24.5): direction (0.005, 0.005, 1) normalised
    np.testing.assert_allclose(dirs[24, 32], np.array([0.005, 0.005, 1]) / np.linalg.norm([0.005, 0.005, 1]))
    np.testing.assert_allclose(cam.world_to_camera @ np.linalg.inv(cam.world_to_camera), np.eye(4), atol=1e-15)
    np.testing.assert_allclose(cam.camera_to_world, np.linalg.inv(cam.world_to_camera), atol=1e-15)
    half = cam.scaled(0.5)
    assert (half.width, half.height) == (32, 24) and half.fx == 50.0


def test_look_at_camera_sees_its_target():
    cam = look_at_camera([3, 1, 2], [0, 0.5, 0], 40, 30, 30.0, "c")
    uv, z = cam.project(np.array([[0, 0.5, 0.0]]))
    np.testing.assert_allclose(uv, [[cam.K[0, 2], cam.K[1, 2]]], atol=1e-9)
    assert z[0] == pytest.approx(np.linalg.norm([3, 0.5, 2]))
    up_uv, _ = cam.project(np.array([[0, 1.5, 0.0]]))
    assert up_uv[0, 1] < uv[0, 1]  # world +Y is up in the image


def test_validation_messages():
    with pytest.raises(PGCDataError, match="camera 'c': field 'R' has 1 non-finite"):
        Camera(K=np.eye(3), R=[[1, 0, 0], [0, 1, 0], [0, 0, np.nan]], t=np.zeros(3), width=2, height=2, name="c")
    with pytest.raises(PGCDataError, match="R is not a rotation"):
        Camera(K=np.eye(3), R=np.diag([1, 1, -1]), t=np.zeros(3), width=2, height=2)
    cam = Camera(K=np.eye(3), R=np.eye(3), t=np.zeros(3), width=4, height=3, name="v")
    with pytest.raises(PGCDataError, match=r"view 'v': image shape \(3, 3, 3\) does not match"):
        View(cam, np.zeros((3, 3, 3)))
    with pytest.raises(PGCDataError, match=r"view 'v': mask shape"):
        View(cam, np.zeros((3, 4, 3)), mask=np.zeros((4, 3)))
    with pytest.raises(PGCDataError, match="camera names must be unique"):
        Capture([View(cam, np.zeros((3, 4, 3))), View(cam, np.zeros((3, 4, 3)))])
    with pytest.raises(PGCDataError, match="capture has no views"):
        Capture([])
    with pytest.raises(PGCDataError, match=r"mesh 'm': face indices out of range \[0, 3\)"):
        Mesh(np.zeros((3, 3)), [[0, 1, 3]], name="m")
    with pytest.raises(PGCDataError, match="uv and face_uv must be given together"):
        Mesh(np.zeros((3, 3)), [[0, 1, 2]], uv=np.zeros((3, 2)))
    with pytest.raises(PGCDataError, match=r"gaussians: 5 SH coefficients is not \(D\+1\)\^2"):
        GaussianSet(np.zeros(1), np.zeros(3), np.zeros(4), np.zeros(3), np.zeros(1), np.zeros((1, 5, 3)))


def test_mesh_geometry_and_submesh():
    cube = seamed_cube()
    cube.vertices = np.round(cube.vertices)
    np.testing.assert_allclose(cube.face_areas(), 0.5)
    assert len(cube.edges()) == 18
    normals = cube.face_normals()
    centroids = cube.vertices[cube.faces].mean(axis=1)
    assert np.all(np.sum(normals * (centroids - 0.5), axis=1) > 0)  # counter-clockwise from outside
    np.testing.assert_allclose(np.linalg.norm(cube.vertex_normals(), axis=1), 1.0)
    degenerate = Mesh(np.zeros((3, 3)), [[0, 1, 2]])
    np.testing.assert_array_equal(degenerate.face_normals(), 0.0)  # zero, not NaN
    sub, used = cube.submesh(cube.face_labels == 2)
    assert len(sub.faces) == int(np.sum(cube.face_labels == 2))
    np.testing.assert_allclose(sub.vertices[sub.faces], cube.vertices[cube.faces[cube.face_labels == 2]])
    np.testing.assert_allclose(sub.uv[sub.face_uv], cube.uv[cube.face_uv[cube.face_labels == 2]])
    np.testing.assert_array_equal(cube.vertices[used], sub.vertices)


@pytest.mark.parametrize("eye, target", [([3, 1, 2], [0, 0.5, 0]), ([0, 0, 0], [0, 0, 1]), ([0, 2, 0], [0, 0, 0]),
                                         ([1, -3, 0.5], [1, 1, 0.5])])
def test_look_at_pose_puts_the_target_on_the_axis_and_up_upward(eye, target):
    from pgc.types import look_at_pose

    R, t = look_at_pose(np.array(eye, float), np.array(target, float))
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    cam = R @ np.asarray(target, float) + t
    np.testing.assert_allclose(cam[:2], 0.0, atol=1e-12)
    assert cam[2] == pytest.approx(np.linalg.norm(np.subtract(target, eye)))
    assert R[1] @ [0.0, 1.0, 0.0] <= 1e-12  # image y points down: world up is never downward in the image
