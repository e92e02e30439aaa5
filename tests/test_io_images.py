"""Image files: exact sRGB code values, 8/16-bit PNG, EXR, masks and label maps, bad files."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from pgc.errors import PGCDataError
from pgc.io.images import (image_size, read_exr, read_image, read_labels, read_mask, write_exr, write_image,
                           write_labels, write_mask)


def test_png8_known_code_values(tmp_path):
    # linear 0.5 -> sRGB 0.735357 -> code 188; linear 0.0031308 -> sRGB 0.04045 -> code 10
    write_image(tmp_path / "a.png", np.array([[[0.5, 0.0031308, 1.0]]], np.float32))
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), [[[188, 10, 255]]])
    back = read_image(tmp_path / "a.png")
    np.testing.assert_allclose(back, [[[((188 / 255 + 0.055) / 1.055) ** 2.4, 10 / 255 / 12.92, 1.0]]], rtol=1e-6)


def test_png16_colour_round_trip(tmp_path):
    img = np.random.default_rng(0).random((5, 7, 3)).astype(np.float32)
    write_image(tmp_path / "b.png", img, bits=16)
    assert (tmp_path / "b.png").read_bytes()[24] == 16  # IHDR bit depth
    np.testing.assert_allclose(read_image(tmp_path / "b.png"), img, atol=2e-4)
    assert image_size(tmp_path / "b.png") == (7, 5)


def test_masks_labels_exr(tmp_path):
    m = np.linspace(0, 1, 12, dtype=np.float32).reshape(3, 4)
    write_mask(tmp_path / "m8.png", m)
    write_mask(tmp_path / "m16.png", m, bits=16)
    np.testing.assert_allclose(read_mask(tmp_path / "m8.png"), m, atol=0.5 / 255)
    np.testing.assert_allclose(read_mask(tmp_path / "m16.png"), m, atol=0.5 / 65535)
    labels = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    write_labels(tmp_path / "l.png", labels)
    np.testing.assert_array_equal(read_labels(tmp_path / "l.png"), labels)
    depth = np.array([[1e-3, 2.5], [1e4, 0.0]], np.float32)
    write_exr(tmp_path / "d.exr", depth)
    np.testing.assert_array_equal(read_exr(tmp_path / "d.exr"), depth)
    assert image_size(tmp_path / "d.exr") == (2, 2)
    hdr = np.full((2, 3, 3), 7.5, np.float32)  # EXR keeps values above 1
    write_image(tmp_path / "h.exr", hdr)
    np.testing.assert_array_equal(read_image(tmp_path / "h.exr"), hdr)


def test_bad_image_files(tmp_path):
    with pytest.raises(PGCDataError, match=r"x\.png: file not found"):
        read_image(tmp_path / "x.png")
    (tmp_path / "bad.png").write_bytes(b"not a png at all, just some bytes padding it out")
    with pytest.raises(PGCDataError, match=r"bad\.png: not a PNG file"):
        read_image(tmp_path / "bad.png")
    Image.fromarray(np.array([[[255, 0, 0]]], np.uint8)).save(tmp_path / "red.png")
    with pytest.raises(PGCDataError, match=r"red\.png: a mask must be a grey image"):
        read_mask(tmp_path / "red.png")
    with pytest.raises(PGCDataError, match=r"label map must be an 8-bit grey PNG"):
        read_labels(tmp_path / "red.png")
    (tmp_path / "a.bmp").write_bytes(b"BM")
    with pytest.raises(PGCDataError, match="unsupported image type '.bmp'"):
        read_image(tmp_path / "a.bmp")


def test_png_refuses_non_finite_and_reads_grey_alpha(tmp_path):
    bad = np.full((2, 2, 3), 0.5, np.float32)
    bad[0, 0, 1] = np.inf  # clipping would silently turn it into a white pixel
    with pytest.raises(PGCDataError, match=r"i\.png: refusing to write 1 non-finite values"):
        write_image(tmp_path / "i.png", bad)
    with pytest.raises(PGCDataError, match=r"m\.png: refusing to write 1 non-finite"):
        write_mask(tmp_path / "m.png", np.array([[0.5, np.nan]], np.float32))
    assert not any(tmp_path.iterdir())
    Image.fromarray(np.array([[[255, 7], [0, 200]]], np.uint8)).save(tmp_path / "la.png")
    np.testing.assert_allclose(read_image(tmp_path / "la.png"), [[[1, 1, 1], [0, 0, 0]]])
