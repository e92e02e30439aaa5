"""transforms.json capture directories: round trips, hand-computed camera conventions, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import make_capture
from pgc.errors import PGCDataError
from pgc.io.capture import opencv_w2c_to_opengl_c2w, opengl_c2w_to_opencv_w2c, read_capture, write_capture
from pgc.io.images import linear_to_srgb, srgb_to_linear


def test_opengl_to_opencv_hand_computed_front_camera():
    # OpenGL camera at (0, 0, 5) looking down -Z with +Y up: identity rotation.
    c2w = np.eye(4)
    c2w[:3, 3] = [0, 0, 5]
    R, t = opengl_c2w_to_opencv_w2c(c2w)
    np.testing.assert_allclose(R, np.diag([1.0, -1.0, -1.0]))
    np.testing.assert_allclose(t, [0.0, 0.0, 5.0])
    # A world point right of and above the origin: x_c = (1, -1, 5) (image y points down).
    np.testing.assert_allclose(R @ [1.0, 1.0, 0.0] + t, [1.0, -1.0, 5.0])


def test_opengl_to_opencv_hand_computed_side_camera():
    # OpenGL camera at (3, 0, 0) looking at the origin (along -X), +Y up: backward axis z = +X,
    # right axis x = y cross z = (0, 0, -1).
    c2w = np.array([[0, 0, 1, 3], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1]], dtype=float)
    R, t = opengl_c2w_to_opencv_w2c(c2w)
    np.testing.assert_allclose(R, [[0, 0, -1], [0, -1, 0], [-1, 0, 0]])
    np.testing.assert_allclose(t, [0, 0, 3])
    np.testing.assert_allclose(R @ [0, 0, 1.0] + t, [-1, 0, 3])  # +Z world is on the camera's left
    np.testing.assert_allclose(opencv_w2c_to_opengl_c2w(R, t), c2w, atol=1e-15)


def test_capture_round_trip_png(tmp_path, small_capture):
    write_capture(tmp_path / "cap", small_capture)
    doc = json.loads((tmp_path / "cap" / "transforms.json").read_text())
    assert doc["frames"][0]["mask_path"] == "masks/cam00.png"
    back = read_capture(tmp_path / "cap")
    assert back.labels == small_capture.labels
    assert back.metadata == small_capture.metadata
    np.testing.assert_allclose(back.light.radiance, small_capture.light.radiance)
    np.testing.assert_array_equal(back.light.envmap, small_capture.light.envmap)
    assert back.light.rotation_deg == 30.0
    for a, b in zip(small_capture.views, back.views):
        assert a.camera.name == b.camera.name
        np.testing.assert_allclose(b.camera.K, a.camera.K, atol=1e-12)
        np.testing.assert_allclose(b.camera.R, a.camera.R, atol=1e-12)
        np.testing.assert_allclose(b.camera.t, a.camera.t, atol=1e-12)
        # 8-bit sRGB quantisation: half a code step in sRGB space, at most ~0.0025 in linear
        np.testing.assert_allclose(linear_to_srgb(b.image), linear_to_srgb(a.image), atol=0.5 / 255 + 1e-6)
        np.testing.assert_allclose(b.mask, a.mask, atol=0.5 / 255 + 1e-6)
        np.testing.assert_array_equal(b.segmentation, a.segmentation)
        np.testing.assert_allclose(linear_to_srgb(b.background), linear_to_srgb(a.background), atol=0.5 / 255 + 1e-6)
        np.testing.assert_array_equal(b.extras["albedo"], a.extras["albedo"])  # EXR float32: exact
        np.testing.assert_array_equal(b.extras["depth"], a.extras["depth"])


@pytest.mark.parametrize("fmt, atol", [("png16", 0.5 / 65535 + 1e-7), ("exr", 0.0)])
def test_capture_round_trip_high_precision(tmp_path, fmt, atol):
    cap = make_capture(n_views=2, seed=3)
    write_capture(tmp_path, cap, image_format=fmt)
    back = read_capture(tmp_path / "transforms.json")
    for a, b in zip(cap.views, back.views):
        np.testing.assert_allclose(linear_to_srgb(b.image) if fmt != "exr" else b.image,
                                   linear_to_srgb(a.image) if fmt != "exr" else a.image, atol=atol)
        np.testing.assert_allclose(b.mask, a.mask, atol=0.5 / 65535 + 1e-7)


def test_capture_without_optional_layers(tmp_path):
    cap = make_capture(n_views=2, layers=False)
    write_capture(tmp_path, cap)
    back = read_capture(tmp_path)
    assert back.light is None and back.views[0].mask is None and back.views[0].extras == {}


def test_srgb_transfer_known_values():
    np.testing.assert_allclose(srgb_to_linear(np.array([0.0, 0.04045, 0.5, 1.0])),
                               [0.0, 0.04045 / 12.92, 0.21404114, 1.0], rtol=1e-6)
    x = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-6)


def test_reads_nerf_synthetic_style(tmp_path):
    """A foreign transforms.json: camera_angle_x, no extension in file_path, no PGC keys."""
    from pgc.io.images import write_image

    write_image(tmp_path / "train" / "r_0.png", np.full((10, 20, 3), 0.5, np.float32))
    c2w = np.eye(4)
    c2w[:3, 3] = [0, 0, 4]
    (tmp_path / "transforms.json").write_text(json.dumps(
        {"camera_angle_x": 2 * np.arctan(1.0), "frames": [{"file_path": "./train/r_0",
                                                            "transform_matrix": c2w.tolist()}]}))
    cap = read_capture(tmp_path)
    cam = cap.views[0].camera
    assert (cam.width, cam.height, cam.name) == (20, 10, "r_0")
    np.testing.assert_allclose(cam.K, [[10, 0, 10], [0, 10, 5], [0, 0, 1]])  # fl = w/2 / tan(45 deg)
    np.testing.assert_allclose(cam.center, [0, 0, 4])


# ------------------------------------------------------------------------------------ bad input


@pytest.fixture
def written(tmp_path):
    write_capture(tmp_path, make_capture(n_views=3, seed=1))
    return tmp_path


def _edit(root, fn):
    path = root / "transforms.json"
    doc = json.loads(path.read_text())
    fn(doc)
    path.write_text(json.dumps(doc))


def test_malformed_json(written):
    (written / "transforms.json").write_text('{"frames": [')
    with pytest.raises(PGCDataError, match=r"transforms\.json: malformed JSON"):
        read_capture(written)


def test_missing_directory(tmp_path):
    with pytest.raises(PGCDataError, match="transforms.json: not found"):
        read_capture(tmp_path / "nope")


def test_missing_image_file(written):
    (written / "images" / "cam01.png").unlink()
    with pytest.raises(PGCDataError, match=r"frames\[1\]\.file_path: file not found: .*cam01\.png"):
        read_capture(written)


def test_missing_mask_file(written):
    (written / "masks" / "cam02.png").unlink()
    with pytest.raises(PGCDataError, match=r"frames\[2\]\.mask_path: file not found"):
        read_capture(written)


def test_image_size_mismatch(written):
    def fn(doc):
        doc["frames"][0]["w"] = 13
    _edit(written, fn)
    with pytest.raises(PGCDataError, match=r"frames\[0\]: image cam00\.png is 12x8 but the intrinsics say w=13"):
        read_capture(written)


def test_layer_size_mismatch(written):
    from pgc.io.images import write_mask

    write_mask(written / "masks" / "cam01.png", np.zeros((8, 11), np.float32))
    with pytest.raises(PGCDataError, match=r"frames\[1\]\.mask_path: cam01\.png is 11x8 but the image is 12x8"):
        read_capture(written)


def test_mask_count_mismatch(written):
    def fn(doc):
        del doc["frames"][1]["mask_path"]
    _edit(written, fn)
    with pytest.raises(PGCDataError, match=r"mask_path: given for 2 of 3 frames \(missing in frames \[1\]\)"):
        read_capture(written)


def test_nan_matrix(written):
    def fn(doc):
        doc["frames"][2]["transform_matrix"][0][3] = float("nan")
    _edit(written, fn)
    with pytest.raises(PGCDataError, match=r"frames\[2\]: 'transform_matrix' holds NaN"):
        read_capture(written)


def test_scaled_matrix_rejected(written):
    def fn(doc):
        m = np.array(doc["frames"][0]["transform_matrix"])
        m[:3, :3] *= 2
        doc["frames"][0]["transform_matrix"] = m.tolist()
    _edit(written, fn)
    with pytest.raises(PGCDataError, match="rotation is not orthonormal"):
        read_capture(written)


def test_no_focal_length(written):
    def fn(doc):
        for f in doc["frames"]:
            del f["fl_x"]
    _edit(written, fn)
    with pytest.raises(PGCDataError, match=r"frames\[0\]: no focal length"):
        read_capture(written)


def test_duplicate_camera_names(written):
    def fn(doc):
        doc["frames"][1]["pgc_name"] = "cam00"
    _edit(written, fn)
    with pytest.raises(PGCDataError, match=r"camera names must be unique; repeated: \['cam00'\]"):
        read_capture(written)


def test_empty_frames(written):
    _edit(written, lambda doc: doc.update(frames=[]))
    with pytest.raises(PGCDataError, match="non-empty list 'frames'"):
        read_capture(written)


def test_unsafe_camera_names_and_shared_intrinsics(tmp_path):
    cap = make_capture(n_views=3, layers=False)
    for view, name in zip(cap.views, ["cam/1", "cam 1", ""]):
        view.camera.name = name
    write_capture(tmp_path, cap)
    doc = json.loads((tmp_path / "transforms.json").read_text())
    assert [f["file_path"] for f in doc["frames"]] == ["images/cam_1.png", "images/cam_1_1.png",
                                                        "images/view002.png"]
    assert [v.camera.name for v in read_capture(tmp_path).views] == ["cam/1", "cam 1", ""]
    # intrinsics given once at the top level apply to every frame (nerfstudio style)
    for key in ("fl_x", "fl_y", "cx", "cy", "w", "h"):
        doc[key] = doc["frames"][0][key]
        for f in doc["frames"]:
            del f[key]
    (tmp_path / "transforms.json").write_text(json.dumps(doc))
    back = read_capture(tmp_path)
    for view in back.views:
        np.testing.assert_allclose(view.camera.K, cap.views[0].camera.K)


def test_distortion_is_kept_or_undistorted(tmp_path):
    from dataclasses import replace

    from pgc.io.images import undistort

    cap = make_capture(n_views=2, width=24, height=16, seed=5)
    dist = np.array([-0.1, 0.02, 0.001, -0.002])
    cap.views[0].camera = replace(cap.views[0].camera, dist=dist)
    write_capture(tmp_path, cap, image_format="exr")
    doc = json.loads((tmp_path / "transforms.json").read_text())
    assert doc["camera_model"] == "OPENCV" and doc["frames"][0]["k1"] == -0.1 and "k1" not in doc["frames"][1]
    kept = read_capture(tmp_path, undistort=False)
    np.testing.assert_array_equal(kept.views[0].camera.dist, dist)
    np.testing.assert_array_equal(kept.views[0].image, cap.views[0].image)
    fixed = read_capture(tmp_path)
    view = fixed.views[0]
    assert view.camera.dist is None
    K = cap.views[0].camera.K
    np.testing.assert_allclose(view.image, undistort(cap.views[0].image, K, dist), atol=1e-6)
    np.testing.assert_array_equal(view.segmentation, undistort(cap.views[0].segmentation, K, dist, "nearest"))
    np.testing.assert_allclose(view.extras["depth"], undistort(cap.views[0].extras["depth"], K, dist), atol=1e-6)
    assert not np.allclose(view.image, cap.views[0].image)  # it did resample
    np.testing.assert_array_equal(fixed.views[1].image, cap.views[1].image)  # the undistorted camera is untouched
