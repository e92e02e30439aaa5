"""COLMAP import: binary files from an independent struct writer, text files, undistortion, bad input."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import look_at_camera
from pgc.errors import PGCDataError
from pgc.io.colmap import capture_from_colmap, read_colmap_model
from pgc.io.images import write_image, write_mask

W, H = 40, 30
MODEL_ID = {"SIMPLE_PINHOLE": 0, "PINHOLE": 1, "OPENCV": 4}


def _qvec(R):
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return [w, x, y, z]


def _scene(model="PINHOLE", params=None):
    cams = [look_at_camera([2.5 * np.sin(a), 0.3, 2.5 * np.cos(a)], [0, 0, 0], W, H, 35.0, f"v{i}")
            for i, a in enumerate([0.0, 1.1, 2.3])]
    points = np.array([[0.1, 0.2, -0.1], [-0.2, 0.0, 0.15], [0.0, -0.1, 0.0]])
    if params is None:
        K = cams[0].K
        params = {"PINHOLE": [K[0, 0], K[1, 1], K[0, 2], K[1, 2]],
                  "SIMPLE_PINHOLE": [K[0, 0], K[0, 2], K[1, 2]]}[model]
    return cams, points, params


def write_binary_model(folder, cams, points, model, params):
    """An independent writer of COLMAP's binary format (one shared camera, id 7)."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "cameras.bin", "wb") as f:
        f.write(struct.pack("<Q", 1))
        f.write(struct.pack("<iiQQ", 7, MODEL_ID[model], W, H))
        f.write(struct.pack(f"<{len(params)}d", *params))
    with open(folder / "images.bin", "wb") as f:
        f.write(struct.pack("<Q", len(cams)))
        for i, cam in enumerate(cams):
            uv, _ = cam.project(points)
            f.write(struct.pack("<i", 10 + i) + struct.pack("<4d", *_qvec(cam.R)) + struct.pack("<3d", *cam.t))
            f.write(struct.pack("<i", 7) + f"{cam.name}.png".encode() + b"\x00")
            f.write(struct.pack("<Q", len(points)))
            for j, (x, y) in enumerate(uv):
                f.write(struct.pack("<ddq", x, y, 100 + j))
    with open(folder / "points3D.bin", "wb") as f:
        f.write(struct.pack("<Q", len(points)))
        for j, p in enumerate(points):
            f.write(struct.pack("<Q3d3BdQ", 100 + j, *p, 10 * j, 20, 30, 0.5, len(cams)))
            for i in range(len(cams)):
                f.write(struct.pack("<ii", 10 + i, j))


def write_text_model(folder, cams, points, model, params):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cameras.txt").write_text(f"# Camera list\n7 {model} {W} {H} " + " ".join(repr(float(x)) for x in params) + "\n")
    lines = ["# Image list with two lines of data per image:"]
    for i, cam in enumerate(cams):
        uv, _ = cam.project(points)
        lines.append(f"{10 + i} " + " ".join(repr(float(x)) for x in [*_qvec(cam.R), *cam.t]) + f" 7 {cam.name}.png")
        lines.append("" if i == 1 else " ".join(f"{float(x)!r} {float(y)!r} {100 + j}" for j, (x, y) in enumerate(uv)))
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    (folder / "points3D.txt").write_text("".join(
        f"{100 + j} {p[0]:.17g} {p[1]:.17g} {p[2]:.17g} {10 * j} 20 30 0.5 10 {j} 11 {j}\n" for j, p in enumerate(points)))


def _images(folder, cams):
    rng = np.random.default_rng(0)
    folder.mkdir(parents=True, exist_ok=True)
    for cam in cams:
        write_image(folder / f"{cam.name}.png", rng.random((H, W, 3)).astype(np.float32))


@pytest.mark.parametrize("writer", [write_binary_model, write_text_model])
@pytest.mark.parametrize("model", ["PINHOLE", "SIMPLE_PINHOLE"])
def test_model_round_trip(tmp_path, writer, model):
    cams, points, params = _scene(model)
    writer(tmp_path / "sparse", cams, points, model, params)
    cameras, images, pts = read_colmap_model(tmp_path / "sparse")
    assert list(cameras) == [7] and cameras[7].model == model
    np.testing.assert_array_equal(pts.ids, [100, 101, 102])
    np.testing.assert_allclose(pts.xyz, points)
    np.testing.assert_array_equal(pts.rgb[:, 0], [0, 10, 20])
    np.testing.assert_allclose(pts.error, 0.5)
    for i, cam in enumerate(cams):
        img = images[10 + i]
        np.testing.assert_allclose(img.rotation(), cam.R, atol=1e-12)
        np.testing.assert_allclose(img.tvec, cam.t)
        if not (writer is write_text_model and i == 1):
            np.testing.assert_array_equal(img.point3d_ids, [100, 101, 102])

    _images(tmp_path / "images", cams)
    capture = capture_from_colmap(tmp_path / "sparse", tmp_path / "images")
    assert [v.camera.name for v in capture.views] == ["v0", "v1", "v2"]
    assert capture.metadata["colmap"]["num_points"] == 3
    for view, cam in zip(capture.views, cams):
        # the recorded keypoints are the projections of the 3D points through the imported camera
        uv, z = view.camera.project(points)
        ref_uv, _ = cam.project(points)
        np.testing.assert_allclose(uv, ref_uv, atol=1e-9 if model == "PINHOLE" else 0.5)
        assert np.all(z > 0)


def _distort(xn, yn, k1, k2, p1, p2):
    """OpenCV's radial-tangential distortion of normalised coordinates (written out by hand)."""
    r2 = xn * xn + yn * yn
    radial = 1 + k1 * r2 + k2 * r2 * r2
    return (xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn),
            yn * radial + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn)


def test_opencv_model_is_undistorted(tmp_path):
    cams, points, _ = _scene("PINHOLE")
    fx, fy, cx, cy = 35.0, 36.0, W / 2 + 0.3, H / 2 - 0.2
    dist = (-0.08, 0.01, 0.002, -0.001)
    write_binary_model(tmp_path / "sparse", cams[:1], points, "OPENCV", [fx, fy, cx, cy, *dist])

    def h(u, v):  # a smooth pattern over distorted pixel coordinates
        return 0.5 + 0.4 * np.sin(0.35 * u) * np.cos(0.3 * v)

    # the distorted image holds h at its pixel centres (pixel (i, j) centre = (j + 0.5, i + 0.5))
    vv, uu = np.mgrid[0:H, 0:W] + 0.5
    (tmp_path / "images").mkdir()
    from pgc.io.images import write_exr

    write_exr(tmp_path / "images" / "v0.exr", np.repeat(h(uu, vv)[..., None], 3, axis=2))
    (tmp_path / "sparse" / "images.bin").unlink()
    # rewrite images.bin pointing at the EXR (linear, no quantisation)
    with open(tmp_path / "sparse" / "images.bin", "wb") as f:
        f.write(struct.pack("<Q", 1) + struct.pack("<i", 1) + struct.pack("<4d", *_qvec(cams[0].R))
                + struct.pack("<3d", *cams[0].t) + struct.pack("<i", 7) + b"v0.exr\x00" + struct.pack("<Q", 0))
    write_mask(tmp_path / "images" / "v0.exr.png", np.ones((H, W), np.float32))
    cap = capture_from_colmap(tmp_path / "sparse", tmp_path / "images", mask_dir=tmp_path / "images")
    view = cap.views[0]
    assert view.camera.dist is None
    np.testing.assert_allclose(view.camera.K, [[fx, 0, cx], [0, fy, cy], [0, 0, 1]])
    # the undistorted pixel p sees the distorted image at distort(p)
    xd, yd = _distort((uu - cx) / fx, (vv - cy) / fy, *dist)
    expected = h(fx * xd + cx, fy * yd + cy)
    inner = (slice(3, -3), slice(3, -3))
    err = np.abs(view.image[..., 0] - expected)[inner]
    assert err.max() < 0.01, err.max()  # bilinear resampling of a smooth pattern
    assert view.mask[inner].min() == 1.0


def test_missing_camera_reference(tmp_path):
    cams, points, params = _scene()
    write_binary_model(tmp_path, cams, points, "PINHOLE", params)
    data = (tmp_path / "cameras.bin").read_bytes()
    (tmp_path / "cameras.bin").write_bytes(data[:8] + struct.pack("<i", 3) + data[12:])  # camera id 7 -> 3
    with pytest.raises(PGCDataError, match=r"image 10 \('v0\.png'\) references camera 7, .* ids \[3\]"):
        read_colmap_model(tmp_path)


def test_bad_models(tmp_path):
    with pytest.raises(PGCDataError, match="no cameras.bin or cameras.txt"):
        read_colmap_model(tmp_path)
    cams, points, params = _scene()
    write_binary_model(tmp_path / "a", cams, points, "PINHOLE", params)
    data = (tmp_path / "a" / "images.bin").read_bytes()
    (tmp_path / "a" / "images.bin").write_bytes(data[:50])
    with pytest.raises(PGCDataError, match=r"images\.bin: truncated binary file"):
        read_colmap_model(tmp_path / "a")
    write_text_model(tmp_path / "b", cams, points, "PINHOLE", params)
    (tmp_path / "b" / "cameras.txt").write_text("7 PINHOLE 40 30 1 2 3\n")
    with pytest.raises(PGCDataError, match=r"cameras\.txt:1: PINHOLE takes 4 parameters, got 3"):
        read_colmap_model(tmp_path / "b")
    (tmp_path / "b" / "cameras.txt").write_text("7 OPENCV_FISHEYE 40 30 1 2 3 4 5 6 7 8\n")
    _images(tmp_path / "img", cams)
    with pytest.raises(PGCDataError, match="uses the COLMAP model OPENCV_FISHEYE; supported"):
        capture_from_colmap(tmp_path / "b", tmp_path / "img")


def test_missing_and_mis_sized_images(tmp_path):
    cams, points, params = _scene()
    write_binary_model(tmp_path / "s", cams, points, "PINHOLE", params)
    _images(tmp_path / "img", cams)
    (tmp_path / "img" / "v1.png").unlink()
    with pytest.raises(PGCDataError, match=r"v1\.png: image 'v1\.png' of the COLMAP model not found"):
        capture_from_colmap(tmp_path / "s", tmp_path / "img")
    write_image(tmp_path / "img" / "v1.png", np.zeros((H, W + 1, 3), np.float32))
    with pytest.raises(PGCDataError, match=r"v1\.png: image is 41x30 but COLMAP camera 7 is 40x30"):
        capture_from_colmap(tmp_path / "s", tmp_path / "img")


@pytest.mark.parametrize("fmt", ["text", "binary"])
def test_agrees_with_real_colmap(tmp_path, fmt):
    """pycolmap (COLMAP itself) reads the struct-written model and writes it again; we read its output."""
    pycolmap = pytest.importorskip("pycolmap")
    cams, points, params = _scene("PINHOLE")
    write_binary_model(tmp_path / "ours", cams, points, "PINHOLE", params)
    rec = pycolmap.Reconstruction(str(tmp_path / "ours"))
    assert (rec.num_images(), rec.num_points3D()) == (3, 3)
    (tmp_path / "colmap").mkdir()
    getattr(rec, f"write_{fmt}")(str(tmp_path / "colmap"))
    cameras, images, pts = read_colmap_model(tmp_path / "colmap")
    np.testing.assert_allclose(cameras[7].params, params)
    np.testing.assert_allclose(pts.xyz[np.argsort(pts.ids)], points)
    for i, cam in enumerate(cams):
        np.testing.assert_allclose(images[10 + i].rotation(), cam.R, atol=1e-12)
        np.testing.assert_allclose(images[10 + i].tvec, cam.t, atol=1e-12)
        assert images[10 + i].name == f"{cam.name}.png"
        np.testing.assert_allclose(images[10 + i].xys, cam.project(points)[0], atol=1e-9)
