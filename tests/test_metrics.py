"""Metrics psnr, psnr-exposure, ssim, fsim: analytic values, an independent SSIM (scikit-image), FSIM properties and piq."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from pgc.errors import PGCConfigError, PGCDataError
from pgc.io.images import linear_to_srgb, srgb_to_linear
from pgc.metrics.common import mask_bbox
from pgc.metrics.fsim import _block_average, downsample_factor
from pgc.metrics.ssim import K1, K2
from pgc.registry import default_registry


def metric(name: str, **options):
    return default_registry().create("metric", name, options or None)


def textured(h: int = 64, w: int = 80, seed: int = 0) -> np.ndarray:
    """A linear image with structure at several scales (sRGB values in [0.1, 0.9])."""
    rng = np.random.default_rng(seed)
    srgb = sum(gaussian_filter(rng.standard_normal((h, w, 3)), (s, s, 0)) * s for s in (0.7, 2, 6))
    srgb = 0.1 + 0.8 * (srgb - srgb.min()) / (srgb.max() - srgb.min())
    return srgb_to_linear(srgb)


def shifted_in_display(image: np.ndarray, offset: float) -> np.ndarray:
    """The linear image whose sRGB values are ``image``'s plus ``offset``."""
    return srgb_to_linear(linear_to_srgb(image) + offset)


@pytest.mark.parametrize("name", ["psnr", "psnr-exposure", "ssim", "fsim"])
def test_identical_images_give_the_best_value(name):
    image = textured()
    best = {"psnr": np.inf, "psnr-exposure": np.inf, "ssim": 1.0, "fsim": 1.0}[name]
    assert metric(name)(image, image) == pytest.approx(best, abs=1e-12)


def test_registered_with_their_direction():
    reg = default_registry()
    for name in ("psnr", "psnr-exposure", "ssim", "fsim", "lpips"):
        impl = reg.get("metric", name)
        assert impl.available, impl.reason
    assert all(reg.create("metric", n).higher_is_better for n in ("psnr", "psnr-exposure", "ssim", "fsim"))


@pytest.mark.parametrize("offset", [0.01, 0.05, 0.1])
def test_psnr_of_a_uniform_offset(offset):
    image = textured()
    assert metric("psnr", color_space="linear")(image, np.clip(image + offset, 0, 2)) == pytest.approx(
        -20 * np.log10(offset), rel=1e-5)
    assert metric("psnr")(shifted_in_display(image, offset), image) == pytest.approx(-20 * np.log10(offset), rel=1e-4)


def test_psnr_mask_counts_only_the_masked_pixels():
    image = textured()
    pred = image.copy()
    pred[:, 40:] = 0.0  # wrong only outside the mask
    mask = np.zeros(image.shape[:2], np.float32)
    mask[:, :40] = 1.0
    noisy = shifted_in_display(image, 0.1)
    assert metric("psnr")(pred, image, mask) == np.inf
    assert metric("psnr")(noisy, image, mask) == pytest.approx(20.0, rel=1e-4)


def test_ssim_of_a_constant_shift_matches_the_formula():
    """For constant images a and a + c the variances vanish: SSIM = (2 a (a + c) + C1) / (a^2 + (a + c)^2 + C1)."""
    a, c = 0.4, 0.15
    x = np.full((32, 32, 3), a)
    expected = (2 * a * (a + c) + K1 ** 2) / (a ** 2 + (a + c) ** 2 + K1 ** 2)
    assert metric("ssim")(srgb_to_linear(x + c), srgb_to_linear(x)) == pytest.approx(expected, rel=1e-5)


def test_ssim_of_a_contrast_change_matches_the_formula():
    """y = m + s (x - m) on a +-amp checkerboard around m. With the window's local mean mu_x = m + d, the local
    variance is amp^2 - d^2, cov = s var, var_y = s^2 var and mu_y = m + s d, so SSIM is analytic per pixel."""
    from pgc.metrics.ssim import ssim_map

    m, s, amp = 0.5, 0.5, 0.2
    yy, xx = np.mgrid[:40, :40]
    x = m + amp * np.where((yy + xx) % 2, 1.0, -1.0)[..., None] * np.ones(3)
    y = m + s * (x - m)
    inner = (slice(12, -12), slice(12, -12))  # away from the reflected border
    d = (gaussian_filter(x, (1.5, 1.5, 0), truncate=3.5) - m)[inner]
    var = amp ** 2 - d ** 2
    mu_x, mu_y = m + d, m + s * d
    expected = ((2 * mu_x * mu_y + K1 ** 2) / (mu_x ** 2 + mu_y ** 2 + K1 ** 2)
                * (2 * s * var + K2 ** 2) / ((1 + s ** 2) * var + K2 ** 2))
    assert np.allclose(ssim_map(y, x)[inner], expected, rtol=1e-6)


def test_ssim_matches_scikit_image():
    skm = pytest.importorskip("skimage.metrics", reason="scikit-image is the independent SSIM check")
    rng = np.random.default_rng(4)
    for _ in range(3):
        a = textured(45, 61, seed=int(rng.integers(100)))
        b = srgb_to_linear(np.clip(linear_to_srgb(a) + 0.05 * rng.standard_normal(a.shape), 0, 1))
        ref = skm.structural_similarity(linear_to_srgb(a).astype(np.float64), linear_to_srgb(b).astype(np.float64),
                                        gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                        data_range=1.0, channel_axis=-1)
        assert metric("ssim")(a, b) == pytest.approx(ref, abs=1e-6)


@pytest.mark.parametrize("padding", ["reflect", "zeros"])
def test_ssim_map_and_srgb_are_one_code_for_numpy_torch_and_jax(padding):
    """The metric's SSIM map and the fit's loss are one function: torch and JAX (float64) give numpy's values,
    and so do the sRGB transfer functions."""
    torch = pytest.importorskip("torch")
    jnp = pytest.importorskip("jax.numpy")
    import jax

    from pgc.metrics.ssim import mean_ssim, ssim_map

    rng = np.random.default_rng(8)
    x = rng.uniform(size=(19, 23, 3))
    y = np.clip(x + 0.1 * rng.normal(size=x.shape), 0.0, 1.0)
    ref = ssim_map(x, y, padding)
    np.testing.assert_allclose(ssim_map(torch.tensor(x), torch.tensor(y), padding).numpy(), ref, atol=1e-12)
    with jax.enable_x64(True):
        np.testing.assert_allclose(np.asarray(ssim_map(jnp.asarray(x), jnp.asarray(y), padding)), ref, atol=1e-12)
        np.testing.assert_allclose(float(mean_ssim(jnp.asarray(x), jnp.asarray(y))),
                                   ssim_map(x, y, "zeros").mean(), atol=1e-12)
        v = np.linspace(-0.1, 1.1, 101)
        for f in (linear_to_srgb, srgb_to_linear):
            np.testing.assert_allclose(f(torch.tensor(v)).numpy(), f(v), atol=1e-7)
            np.testing.assert_allclose(np.asarray(f(jnp.asarray(v))), f(v), atol=1e-7)


def test_ssim_mask_of_ones_equals_unmasked_and_mask_restricts():
    a = textured()
    b = a.copy()
    b[:, 50:] = a[::-1, 50:]  # structure broken on the right
    mask = np.zeros(a.shape[:2])
    mask[:, :40] = 1
    assert metric("ssim")(b, a, np.ones(a.shape[:2])) == pytest.approx(metric("ssim")(b, a), abs=1e-12)
    assert metric("ssim")(b, a, mask) == pytest.approx(1.0, abs=1e-12)
    assert metric("ssim")(b, a) < 0.9


def test_fsim_is_symmetric():
    a, b = textured(seed=1), textured(seed=2)
    assert metric("fsim")(a, b) == pytest.approx(metric("fsim")(b, a), abs=1e-12)


@pytest.mark.parametrize("distortion", ["blur", "noise"])
def test_fsim_decreases_as_the_distortion_grows(distortion):
    rng = np.random.default_rng(5)
    a = textured(96, 96)
    noise = rng.standard_normal(a.shape)
    values = []
    for level in (0.5, 1.0, 2.0, 4.0):
        srgb = linear_to_srgb(a)
        srgb = gaussian_filter(srgb, (level, level, 0)) if distortion == "blur" else srgb + 0.03 * level * noise
        values.append(metric("fsim")(srgb_to_linear(np.clip(srgb, 0, 1)), a))
    assert all(x > y for x, y in zip(values, values[1:])) and values[0] < 1.0


def test_fsim_grey_variant_and_masks():
    a = textured(seed=3)
    b = srgb_to_linear(np.clip(linear_to_srgb(a) + 0.05, 0, 1))
    b[:, 60:] = a[:, 60:][:, ::-1]  # structure broken on the right only
    right = np.zeros(a.shape[:2])
    right[:, 60:] = 1
    left = 1 - right
    fsim = metric("fsim")
    assert fsim(b, a, np.ones(a.shape[:2])) == pytest.approx(fsim(b, a), abs=1e-12)
    assert fsim(b, a, left) > fsim(b, a) > fsim(b, a, right)
    assert metric("fsim", chromatic=False)(b, a) != fsim(b, a)


def test_fsim_downsampling_follows_the_reference():
    assert [downsample_factor(h, 1000) for h in (200, 383, 384, 639, 640, 1080)] == [1, 1, 2, 2, 3, 4]
    x = np.arange(1.0, 26.0).reshape(5, 5)
    # MATLAB conv2(x, ones(2)/4, 'same')(1:2:end, 1:2:end): the mean of each pixel with its lower/right
    # neighbours, zeros beyond the border
    padded = np.pad(x, ((0, 1), (0, 1)))
    expected = (padded[:-1, :-1] + padded[1:, :-1] + padded[:-1, 1:] + padded[1:, 1:])[::2, ::2] / 4
    assert np.allclose(_block_average(x[..., None], 2)[..., 0], expected)


def test_fsim_flat_images_are_finite():
    flat = np.full((40, 40, 3), 0.3, np.float32)
    assert metric("fsim")(flat, flat) == pytest.approx(1.0)
    assert np.isfinite(metric("fsim")(flat * 0.5, flat))


def test_fsim_filter_bank_is_built_once_per_size_and_read_only():
    """The cached log-Gabor bank gives the same value as a freshly built one, whatever sizes came before."""
    from pgc.metrics.fsim import _bank

    a, b = textured(48, 56, seed=1), textured(48, 56, seed=2)
    _bank.cache_clear()
    fresh = metric("fsim")(a, b)
    metric("fsim")(textured(40, 64, seed=3), textured(40, 64, seed=4))  # another size in between
    assert metric("fsim")(a, b) == fresh
    assert _bank.cache_info().misses == 2
    with pytest.raises(ValueError):
        _bank(48, 56).filters[0][0][0, 0] = 1.0


def _bench():
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "bench_metrics", Path(__file__).resolve().parents[1] / "benchmarks" / "bench_metrics.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def _import_piq():
    pytest.importorskip("torch")
    try:
        return _bench().import_piq()
    except ImportError:
        pytest.skip("piq is not installed (test-only cross-check; pip install --no-deps piq==0.8.0)")


@pytest.mark.parametrize("size", [(64, 80), pytest.param((400, 420), marks=pytest.mark.slow)])  # 2nd: F = 2
def test_fsim_agrees_with_piq(size):
    piq = _import_piq()
    import torch

    a = textured(*size, seed=6)
    rng = np.random.default_rng(7)
    b = srgb_to_linear(np.clip(linear_to_srgb(a) + 0.05 * rng.standard_normal(a.shape), 0, 1))

    def tensor(x):
        return torch.from_numpy(linear_to_srgb(x).astype(np.float64)).permute(2, 0, 1)[None]

    for chromatic in (True, False):
        ref = float(piq.fsim(tensor(b), tensor(a), data_range=1.0, chromatic=chromatic))
        assert metric("fsim", chromatic=chromatic)(b, a) == pytest.approx(ref, abs=2e-3)


def test_bad_inputs_are_clear_errors():
    a = textured()
    with pytest.raises(PGCDataError, match="shape"):
        metric("psnr")(a, a[:10])
    with pytest.raises(PGCDataError, match="mask shape"):
        metric("ssim")(a, a, np.ones((3, 3)))
    with pytest.raises(PGCDataError, match="empty"):
        metric("psnr")(a, a * 0.5, np.zeros(a.shape[:2]))
    with pytest.raises(PGCDataError, match="window"):
        metric("ssim")(a[:8, :8], a[:8, :8])


def test_mask_bbox_grows_to_the_minimum_size_inside_the_image():
    mask = np.zeros((50, 60))
    mask[2:5, 55:58] = 1
    rows, cols = mask_bbox(mask, 32)
    assert (rows.start, rows.stop, cols.start, cols.stop) == (0, 32, 28, 60)
    assert mask[rows, cols].sum() == mask.sum()
    rows, cols = mask_bbox(mask, 1)
    assert (rows.start, rows.stop, cols.start, cols.stop) == (2, 5, 55, 58)


def test_benchmark_script_runs_and_writes_records(tmp_path):
    out = tmp_path / "bench.json"
    records = _bench().main(["--sizes", "48", "--repeats", "1", "--metrics", "psnr", "ssim", "fsim", "--out", str(out)])
    assert out.is_file() and {r["implementation"] for r in records} == {"psnr", "ssim", "fsim"}
    assert "torchvision" not in sys.modules  # the piq stand-in does not leak
    for r in records:
        if "abs_diff_independent" in r["errors"]:
            assert r["errors"]["abs_diff_independent"] < 2e-3, r


def test_psnr_exposure_of_a_constant_scale_error_matches_the_formula():
    """Target c, prediction c (1 + e): scaled to the mid-grey g they are g and g (1 + e) whatever c is, so the
    PSNR is -20 log10(srgb(g (1 + e)) - srgb(g))."""
    g, e = 0.18, 0.1
    expected = -20 * np.log10(float(linear_to_srgb(np.float64(g * (1 + e))) - linear_to_srgb(np.float64(g))))
    for c in (0.02, 0.18, 0.6):
        target = np.full((16, 16, 3), c)
        assert metric("psnr-exposure")(target * (1 + e), target) == pytest.approx(expected, rel=1e-5)


def test_psnr_exposure_does_not_depend_on_the_light_level():
    """One relative error under a light 1, 10 and 100 times dimmer: plain sRGB PSNR rises as the light dims (by
    more than 3 dB here), the exposure-normalised PSNR stays put."""
    target = textured()
    pred = shifted_in_display(target, 0.05)
    plain = [metric("psnr")(k * pred, k * target) for k in (1.0, 0.1, 0.01)]
    exposed = [metric("psnr-exposure")(k * pred, k * target) for k in (1.0, 0.1, 0.01)]
    assert plain[1] > plain[0] + 3.0 and plain[2] > plain[1] + 3.0
    assert exposed == pytest.approx([exposed[0]] * 3, rel=1e-6)


def test_psnr_exposure_is_psnr_when_the_target_is_at_the_exposure():
    target = textured()
    target = target * (0.18 / target.mean())
    pred = shifted_in_display(target, 0.03)
    assert metric("psnr-exposure")(pred, target) == pytest.approx(metric("psnr")(pred, target), rel=1e-6)
    assert metric("psnr-exposure", exposure=0.5)(pred, target) != pytest.approx(metric("psnr")(pred, target), rel=1e-3)


def test_psnr_exposure_takes_the_mean_over_the_mask():
    """Light outside the mask changes neither the scale nor the error."""
    target = textured()
    pred = shifted_in_display(target, 0.05)
    mask = np.zeros(target.shape[:2], np.float32)
    mask[:, :40] = 1.0
    brighter = target.copy()
    brighter[:, 40:] = 1.0
    assert metric("psnr-exposure")(pred, brighter, mask) == pytest.approx(
        metric("psnr-exposure")(pred, target, mask), rel=1e-9)


def test_psnr_exposure_refuses_a_black_target_and_stays_finite_near_it():
    from pgc.metrics.psnr import BLACK

    pred = textured()
    with pytest.raises(PGCDataError, match="black"):
        metric("psnr-exposure")(pred, np.zeros_like(pred))
    target = textured() * (2 * BLACK / textured().mean())  # barely above black: a factor of about 1e5
    value = metric("psnr-exposure")(target * 1.2, target)
    assert np.isfinite(value)
    assert value == pytest.approx(metric("psnr-exposure")(textured() * 1.2, textured()), rel=1e-6)
    with pytest.raises(PGCConfigError, match="option 'exposure'"):
        metric("psnr-exposure", exposure=0.0)
