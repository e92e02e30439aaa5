"""Albedo estimators: the ONNX model contract, tiling, the shading-ratio baseline, robustness."""

import numpy as np
import pytest

from pgc.albedo.dataset import scale_invariant_error
from pgc.albedo.shading_ratio import ShadingRatioEstimator
from pgc.errors import PGCDataError
from pgc.synth.albedo_data import random_palette

torch = pytest.importorskip("torch", reason="exporting test models needs torch (pgc[torch])")
pytest.importorskip("onnxruntime", reason="the onnx estimator needs onnxruntime (pgc[onnx])")
pytest.importorskip("onnx", reason="exporting test models needs onnx (pgc[train])")

from pgc_onnx.albedo import OnnxAlbedoEstimator  # noqa: E402
from pgc_torch.albedo.net import AlbedoUNet, export_onnx  # noqa: E402


@pytest.fixture(scope="module")
def random_model(tmp_path_factory):
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("m") / "unet.onnx"
    export_onnx(AlbedoUNet(width=8), str(path))
    return path


def test_missing_model_file_names_the_path_and_the_fix(tmp_path):
    with pytest.raises(PGCDataError, match="nothere.onnx.*train_albedo"):
        OnnxAlbedoEstimator({"model": str(tmp_path / "nothere.onnx")})


def test_a_file_that_is_not_onnx_is_rejected(tmp_path):
    bad = tmp_path / "bad.onnx"
    bad.write_text("not a model")
    with pytest.raises(PGCDataError, match="not a loadable ONNX model"):
        OnnxAlbedoEstimator({"model": str(bad)})


def test_wrong_input_shape_and_missing_output_are_rejected(tmp_path):
    class OneChannel(torch.nn.Module):
        def forward(self, x):
            return x * 2

    path = tmp_path / "gray.onnx"
    torch.onnx.export(OneChannel(), (torch.rand(1, 1, 8, 8),), str(path), input_names=["image"],
                      output_names=["albedo"], dynamo=False)
    with pytest.raises(PGCDataError, match=r"\(N, 3, H, W\)"):
        OnnxAlbedoEstimator({"model": str(path)})
    path2 = tmp_path / "noalbedo.onnx"
    torch.onnx.export(OneChannel(), (torch.rand(1, 3, 8, 8),), str(path2), input_names=["image"],
                      output_names=["shading"], dynamo=False)
    with pytest.raises(PGCDataError, match="no output named 'albedo'"):
        OnnxAlbedoEstimator({"model": str(path2)})


def test_output_matches_torch_and_is_in_range(random_model):
    est = OnnxAlbedoEstimator({"model": str(random_model)})
    img = np.random.default_rng(0).uniform(0, 1, (30, 42, 3)).astype(np.float32)  # not a multiple of 4
    out = est.estimate(img)
    assert out.shape == img.shape and out.dtype == np.float32
    assert np.all((out >= 0) & (out <= 1))


def test_tiling_equals_a_whole_image_run_away_from_tile_borders(random_model):
    whole = OnnxAlbedoEstimator({"model": str(random_model), "tile": 4096})
    tiled = OnnxAlbedoEstimator({"model": str(random_model), "tile": 96, "overlap": 32})
    rng = np.random.default_rng(1)
    img = np.repeat(np.repeat(rng.uniform(0, 1, (40, 60, 3)), 4, 0), 4, 1).astype(np.float32)  # 160 x 240
    a, b = whole.estimate(img), tiled.estimate(img)
    # the receptive field (about 22 px) fits in half the overlap, so the blend is exact up to float noise
    np.testing.assert_allclose(a, b, atol=2e-4)


def test_nan_and_out_of_range_input_give_finite_albedo(random_model):
    est = OnnxAlbedoEstimator({"model": str(random_model)})
    img = np.full((16, 16, 3), 0.5, np.float32)
    img[3, 4] = np.nan
    img[5, 5] = 7.0
    img[6, 6] = -1.0
    assert np.all(np.isfinite(est.estimate(img)))


def test_shading_ratio_recovers_albedo_and_stays_finite_where_shading_vanishes():
    rng = np.random.default_rng(2)
    albedo = rng.uniform(0.1, 0.9, (20, 20, 3)).astype(np.float32)
    shading = rng.uniform(0.2, 2.0, (20, 20, 3)).astype(np.float32)
    shading[:5] = 0.0
    est = ShadingRatioEstimator()
    out = est.estimate(albedo * shading, shading=shading)
    np.testing.assert_allclose(out[5:], albedo[5:], rtol=1e-5)
    assert np.all(np.isfinite(out)) and np.all(out[:5] == 0)
    with pytest.raises(PGCDataError, match="needs the shading"):
        est.estimate(albedo)


def test_scale_invariant_error_ignores_a_global_scale():
    rng = np.random.default_rng(3)
    a = rng.uniform(0.1, 0.9, (10, 10, 3))
    w = np.ones((10, 10))
    assert scale_invariant_error(a * np.array([0.5, 2.0, 1.3]), a, w) < 1e-12
    assert scale_invariant_error(a + 0.1, a, w) > 0.01


def test_random_palette_is_deterministic_and_in_range():
    p1 = random_palette(np.random.default_rng(5), 3)
    assert p1 == random_palette(np.random.default_rng(5), 3)
    assert all(0 <= c <= 1 for col in p1 for c in col)


def test_random_fabric_and_light_are_deterministic_and_varied():
    from pgc.synth.albedo_data import PATTERNS, random_fabric, random_light

    fabrics = [random_fabric(np.random.default_rng([9, s])) for s in range(40)]
    assert fabrics[3] == random_fabric(np.random.default_rng([9, 3]))
    assert {f.pattern.split("+")[0] for f in fabrics} == set(PATTERNS)
    assert any(f.pattern.endswith("+logo") for f in fabrics)
    assert all(len(f.colors) == 3 for f in fabrics)
    lights = [random_light(np.random.default_rng([9, s])) for s in range(30)]
    assert any(light.envmap is not None for light in lights) and any(light.envmap is None for light in lights)
    again = random_light(np.random.default_rng([9, 7]))
    np.testing.assert_array_equal(again.radiance, lights[7].radiance)


def test_shading_smoothing_keeps_the_pattern_and_drops_pixel_level_errors():
    from pgc_onnx.albedo import smooth_shading

    rng = np.random.default_rng(3)
    h, w = 64, 80
    stripes = np.where((np.arange(h)[:, None, None] // 3) % 2 == 0, 0.7, 0.1) * np.array([1.0, 0.8, 0.6])
    albedo = np.broadcast_to(stripes, (h, w, 3))
    shading = (0.6 + 0.3 * np.linspace(0, 1, w))[None, :, None] * np.ones((h, 1, 3))  # smooth ramp
    image = albedo * shading
    # a prediction with the right shading in the mean but per-pixel multiplicative errors (+-20 %)
    noisy = np.clip(albedo * rng.uniform(0.8, 1.2, albedo.shape), 0, 1)
    mask = np.zeros((h, w))
    mask[4:-4, 4:-4] = 1
    out = smooth_shading(image, noisy, mask, 13)
    inner = mask > 0
    inner[:10] = inner[-10:] = False
    err_pred = scale_invariant_error(noisy, albedo, inner.astype(float))
    err_out = scale_invariant_error(out, albedo, inner.astype(float))
    assert err_out < 0.35 * err_pred
    # an exact prediction under exactly constant shading is returned unchanged
    exact = smooth_shading(albedo * 0.5, albedo, mask, 13)
    np.testing.assert_allclose(exact[inner], albedo[inner], atol=1e-9)


def test_shading_smoothing_is_finite_where_albedo_image_or_mask_vanish():
    from pgc_onnx.albedo import smooth_shading

    img = np.zeros((20, 20, 3))
    img[5:15, 5:15] = 0.4
    pred = np.zeros_like(img)
    pred[8:12] = 0.5
    for mask in (None, np.zeros((20, 20)), np.ones((20, 20))):
        out = smooth_shading(img, pred, mask, 7)
        assert np.all(np.isfinite(out)) and out.min() >= 0 and out.max() <= 1
