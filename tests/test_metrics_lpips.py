"""LPIPS: the published reference distances, masks, weight provenance, and the safe weight conversion."""

from __future__ import annotations

import hashlib
import importlib.util
import io
import json
import os
import pickle
from pathlib import Path

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.io.images import read_image
from pgc.metrics.weights import PACKAGE_DATA, lpips_weights_path

pytest.importorskip("torch")
DATA = Path(__file__).parent / "data" / "lpips"
SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "convert_lpips_weights.py"


def lpips(net: str = "alex"):
    from pgc.registry import default_registry

    return default_registry().create("metric", "lpips", {"net": net})


@pytest.fixture(scope="module")
def pair():
    return tuple(read_image(DATA / f"ex_{n}.png") for n in ("ref", "p0", "p1"))


def test_reference_distances_alexnet(pair):
    """Zhang et al.'s example pair: LPIPS(ref, p0) = 0.722, LPIPS(ref, p1) = 0.138 (AlexNet, v0.1 heads)."""
    ref, p0, p1 = pair
    metric = lpips()
    assert not metric.higher_is_better
    assert round(metric(p0, ref), 3) == 0.722
    assert round(metric(p1, ref), 3) == 0.138
    assert metric(ref, ref) == 0.0
    assert metric(p0, ref) == pytest.approx(metric(ref, p0), abs=1e-7)


@pytest.mark.slow
def test_vgg_backbone(pair):
    try:
        lpips_weights_path("vgg")
    except Exception as exc:  # not converted on this machine
        pytest.skip(f"VGG weights not converted here ({exc})")
    ref, p0, p1 = pair
    metric = lpips("vgg")
    assert metric(ref, ref) == 0.0
    assert 0.0 < metric(p1, ref) < metric(p0, ref) < 1.0  # the same ordering as AlexNet and the human judges


def test_mask_of_ones_is_the_plain_distance_and_a_mask_restricts(pair):
    ref, p0, _ = pair
    metric = lpips()
    assert metric(p0, ref, np.ones(ref.shape[:2])) == pytest.approx(metric(p0, ref), rel=1e-6)
    big = np.concatenate([ref, ref], axis=1)
    damaged = big.copy()
    damaged[:, 64:] = p0
    left = np.zeros(big.shape[:2])
    left[:, :64] = 1
    assert metric(damaged, big, left) < 1e-3 < metric(damaged, big)  # the damage lies outside the mask


def test_small_images_are_a_clear_error_unless_masked(pair):
    """Without a mask LPIPS is undefined below the backbone's input size: a clear error. With a mask the image
    is padded by its edge pixels to that size, the padding outside the mask: identical images score 0, and a
    20 x 20 crop of the reference pair keeps the pair's order of distances (p1 closer to ref than p0)."""
    x = np.zeros((20, 20, 3), np.float32)
    with pytest.raises(PGCDataError, match="too small"):
        lpips()(x, x)
    ref, p0, p1 = (a[20:40, 24:44] for a in pair)
    mask = np.ones((20, 20))
    metric = lpips()
    assert metric(ref, ref, mask) == 0.0
    assert 0.0 < metric(p1, ref, mask) < metric(p0, ref, mask) and np.isfinite(metric(p0, ref, mask))


def test_shipped_weights_match_their_record():
    record = json.loads((PACKAGE_DATA / "lpips_alex.json").read_text())
    data = (PACKAGE_DATA / record["file"]).read_bytes()
    assert hashlib.sha256(data).hexdigest() == record["sha256"]
    assert record["heads_ckpt_vs_wheel_max_abs_diff"] == 0.0 and record["float16_max_relative_change"] < 1e-3
    with np.load(io.BytesIO(data), allow_pickle=False) as npz:
        assert npz["conv0.weight"].shape == (64, 3, 11, 11) and npz["lin4.weight"].shape == (256,)


def _script():
    spec = importlib.util.spec_from_file_location("convert_lpips_weights", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_converter_refuses_unverified_files_and_foreign_pickles():
    script = _script()
    with pytest.raises(SystemExit, match="sha256"):
        script.verified(b"not the archive", script.SDIST[2], "x.tar.gz")

    class Payload:
        def __reduce__(self):
            return (os.system, ("echo pwned",))

    with pytest.raises(pickle.UnpicklingError, match="refusing"):
        script._ArraysOnly(io.BytesIO(pickle.dumps({"a": Payload()}))).load()
    arrays = {"w": np.arange(6, dtype=np.float32).reshape(2, 3)}
    assert np.array_equal(script._ArraysOnly(io.BytesIO(pickle.dumps(arrays))).load()["w"], arrays["w"])
