"""The ``filter`` role: torch, JAX and OpenCV against the float64 reference, identities, and hard cases."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.errors import PGCDataError
from pgc.filtering import gaussian_kernel_1d, kernel_size_for_height, odd_size
from pgc.filtering.reference import lowpass_direct, lowpass_separable
from pgc.registry import default_registry

BACKENDS = ("torch", "jax", "opencv")
TOL = 1e-5  # the cross-backend tolerance (float32 backends against the float64 reference)


def create(entry: str):
    """``name`` or ``name:method`` (the OpenCV backend's O(1) approximation 'box3')."""
    name, _, method = entry.partition(":")
    impl = default_registry().get("filter", name)
    if not impl.available:
        pytest.skip(f"filter '{name}' unavailable: {impl.reason}")
    return impl.create({"method": method} if method else None)


@pytest.fixture(scope="module", params=BACKENDS)
def filt(request):
    """The exact backends."""
    return create(request.param)


@pytest.fixture(scope="module", params=BACKENDS + ("opencv:box3",))
def any_filt(request):
    """Every backend, the approximate one included: the properties below hold for any kernel."""
    return create(request.param)


def scene(h: int = 37, w: int = 52, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A random image and a blob-shaped alpha with soft edges, exact zeros and values near zero."""
    rng = np.random.default_rng(seed)
    image = rng.random((h, w, 3)).astype(np.float32)
    yy, xx = np.mgrid[:h, :w]
    d = np.hypot((yy - h / 2) / (h / 3), (xx - w / 2) / (w / 3))
    alpha = np.clip(1.5 - d, 0, 1).astype(np.float32)
    alpha[:3] = 1e-7  # a strip far below the 1e-6 denominator threshold
    return image, alpha


def test_kernel_in_paper_terms():
    assert kernel_size_for_height(2668) == 71
    assert kernel_size_for_height(2 * 2668) == 143
    assert kernel_size_for_height(256) == 7 and kernel_size_for_height(10) == 3
    assert [odd_size(v) for v in (0.2, 1.9, 2.0, 4.4, 6.1)] == [1, 1, 3, 5, 7]
    taps = gaussian_kernel_1d(7)
    assert taps.shape == (7,) and abs(taps.sum() - 1) < 1e-15 and np.allclose(taps, taps[::-1])
    sigma = 7 / 6
    assert np.isclose(taps[4] / taps[3], np.exp(-0.5 / sigma ** 2))


@pytest.mark.parametrize("kernel_size", [1, 3, 9, 31])
def test_separable_reference_equals_direct_sum(kernel_size):
    image, alpha = scene(19, 23)
    assert np.abs(lowpass_separable(image, alpha, kernel_size) - lowpass_direct(image, alpha, kernel_size)).max() < 1e-12


@pytest.mark.agreement
@pytest.mark.parametrize("kernel_size", [1, 5, 21, 71, 151])  # 151 > image: the kernel is clamped to the image
def test_backend_matches_reference(filt, kernel_size):
    image, alpha = scene()
    out = filt.lowpass(image, alpha, kernel_size)
    assert out.dtype == np.float32 and out.shape == image.shape
    assert np.abs(out - lowpass_separable(image, alpha, kernel_size)).max() < TOL


@pytest.mark.agreement
def test_backends_agree_with_each_other():
    reg = default_registry()
    impls = [reg.get("filter", n) for n in BACKENDS]
    outs = [i.create().lowpass(*scene(64, 48, seed=3), 15) for i in impls if i.available]
    assert len(outs) >= 2, "need two filter backends to compare"
    for out in outs[1:]:
        assert np.abs(out - outs[0]).max() < TOL


def test_many_channels(filt):
    rng = np.random.default_rng(1)
    image, alpha = rng.random((20, 17, 7)).astype(np.float32), rng.random((20, 17)).astype(np.float32)
    assert np.abs(filt.lowpass(image, alpha, 9) - lowpass_separable(image, alpha, 9)).max() < TOL


def test_high_plus_low_is_identity(any_filt):
    image, alpha = scene()
    low, high = any_filt.lowpass(image, alpha, 15), any_filt.highpass(image, alpha, 15)
    assert np.abs(low + high - image).max() < 1e-6
    assert np.abs(high).max() > 0.05  # not trivially zero


def test_kernel_size_one_is_identity(any_filt):
    image, alpha = scene()
    assert np.abs(any_filt.lowpass(image, alpha, 1) - image).max() < 1e-6


def test_constant_image_stays_constant(any_filt):
    _, alpha = scene()
    image = np.full(alpha.shape + (3,), 0.0, np.float32) + np.array([0.2, 0.5, 0.9], np.float32)
    assert np.abs(any_filt.lowpass(image, alpha, 31) - image).max() < 1e-6


def test_coloured_background_does_not_bleed_into_the_garment(any_filt):
    """A grey garment (alpha 1) on a saturated red background (alpha 0): the low-pass on the garment stays grey."""
    h, w = 48, 64
    alpha = np.zeros((h, w), np.float32)
    alpha[10:40, 16:50] = 1.0
    image = np.zeros((h, w, 3), np.float32)
    image[...] = (1.0, 0.0, 0.0)
    image[alpha > 0] = (0.4, 0.4, 0.4)
    low = any_filt.lowpass(image, alpha, 25)
    garment = alpha > 0
    assert np.abs(low[garment] - 0.4).max() < 1e-6
    plain = any_filt.lowpass(image, np.ones_like(alpha), 25)  # the same blur without alpha does bleed
    assert np.abs(plain[garment] - 0.4).max() > 0.1


def test_alpha_zero_everywhere_returns_the_image(any_filt):
    image, alpha = scene()
    out = any_filt.lowpass(image, np.zeros_like(alpha), 31)
    assert np.isfinite(out).all() and np.abs(out - image).max() < 1e-7


def test_alpha_near_zero_is_finite_and_continuous(any_filt):
    """Just below and above the 1e-6 threshold the result moves continuously from the image to the mean."""
    image, _ = scene()
    outs = [any_filt.lowpass(image, np.full(image.shape[:2], a, np.float32), 9) for a in (1e-30, 0.99e-6, 1.01e-6, 1e-3)]
    assert all(np.isfinite(o).all() for o in outs)
    assert np.abs(outs[0] - image).max() < 1e-6
    assert np.abs(outs[1] - outs[2]).max() < 0.05  # no jump at the threshold
    assert np.abs(outs[3] - any_filt.lowpass(image, np.ones(image.shape[:2], np.float32), 9)).max() < 1e-5


def test_huge_and_tiny_values_stay_finite(any_filt):
    """The blur is linear in the image. (Below ~1e-31 the products alpha * image with alpha = 1e-7 become
    float32 subnormals, which XLA flushes to zero; so the tiny scale stays above that.)"""
    image, alpha = scene()
    for scale in (1e-20, 1e30):
        out = any_filt.lowpass(image * np.float32(scale), alpha, 11)
        assert np.isfinite(out).all()
        assert np.abs(out / scale - any_filt.lowpass(image, alpha, 11)).max() < 1e-5


@pytest.mark.parametrize("bad", [0, 2, -3, 4.5, True])
def test_bad_kernel_size_is_a_clear_error(filt, bad):
    image, alpha = scene(8, 8)
    with pytest.raises(PGCDataError, match="kernel_size"):
        filt.lowpass(image, alpha, bad)


def test_bad_inputs_are_clear_errors(filt):
    image, alpha = scene(8, 8)
    with pytest.raises(PGCDataError, match="alpha shape"):
        filt.lowpass(image, alpha[:4], 3)
    with pytest.raises(PGCDataError, match=r"\(H, W, C\)"):
        filt.lowpass(image[..., 0], alpha, 3)
    with pytest.raises(PGCDataError, match="NaN"):
        filt.lowpass(np.where(image > 0.5, np.nan, image), alpha, 3)
    with pytest.raises(PGCDataError, match=r"\[0, 1\]"):
        filt.lowpass(image, alpha * 3, 3)


@pytest.fixture
def one_torch_thread():
    """Tiny tensors: a second OpenMP thread only costs (it spins when the shared cores are busy)."""
    torch = pytest.importorskip("torch")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_box_cascade_approximates_the_gaussian():
    """Three boxes match the Gaussian's variance, and the O(1) blur stays close to the exact one on the garment."""
    from pgc.filtering.kernel import box_widths

    for k in (7, 31, 71, 151):
        widths = box_widths(k)
        assert all(w % 2 == 1 for w in widths)
        assert np.sqrt(sum((w * w - 1) / 12 for w in widths)) == pytest.approx(k / 6, rel=0.02)
    image, alpha = scene(64, 64)
    box = create("opencv:box3")
    for k in (9, 31):
        diff = np.abs(box.lowpass(image, alpha, k) - lowpass_separable(image, alpha, k))[alpha > 0.01]
        assert diff.mean() < 5e-3 and diff.max() < 3e-2


def test_torch_gradients_match_finite_differences(one_torch_thread):
    import torch
    from pgc_torch.filter import alpha_lowpass

    image, alpha = scene(7, 9)
    alpha[4:, :5] = 0.0  # exact zeros inside the support
    args = (torch.tensor(image, dtype=torch.float64, requires_grad=True),
            torch.tensor(alpha, dtype=torch.float64, requires_grad=True))
    assert torch.autograd.gradcheck(lambda i, a: alpha_lowpass(i, a, 5), args, eps=1e-6, atol=1e-6, fast_mode=True)


def test_jax_gradient_is_finite_at_zero_alpha_and_matches_torch(one_torch_thread):
    import torch
    jax = pytest.importorskip("jax")
    from pgc_jax.filter import alpha_lowpass as jax_lowpass
    from pgc_torch.filter import alpha_lowpass as torch_lowpass

    image, alpha = scene(12, 10)
    alpha[:, :4] = 0.0
    gi, ga = jax.grad(lambda i, a: jax_lowpass(i, a, 7).sum(), argnums=(0, 1))(image, alpha)
    ti, ta = torch.tensor(image, requires_grad=True), torch.tensor(alpha, requires_grad=True)
    torch_lowpass(ti, ta, 7).sum().backward()
    assert np.isfinite(np.asarray(gi)).all() and np.isfinite(np.asarray(ga)).all()
    # alpha's gradient is large (~1/alpha) where alpha is tiny: compare relatively there
    np.testing.assert_allclose(np.asarray(gi), ti.grad.numpy(), rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(np.asarray(ga), ta.grad.numpy(), rtol=1e-4, atol=1e-4)


def test_benchmark_script_runs_and_writes_records(tmp_path):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_filter.py"
    spec = importlib.util.spec_from_file_location("bench_filter", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    out = tmp_path / "bench.json"
    records = bench.main(["--sizes", "48", "--kernels", "5", "--repeats", "1", "--naive-max", "32",
                          "--backends", "opencv", "--out", str(out)])
    assert len(records) == 1 and out.is_file()
    rec = records[0]
    assert {"role", "implementation", "preset", "settings", "seconds", "peak_mb", "errors", "versions"} <= set(rec)
    assert rec["errors"]["max_abs"] < TOL and rec["settings"]["naive_extrapolated"]
