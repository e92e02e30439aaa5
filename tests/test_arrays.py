"""The array-operations layer (pgc.arrays): numpy, torch and JAX agree in float64, against analytic answers."""

from __future__ import annotations

import contextlib
import subprocess
import sys

import numpy as np
import pytest

from pgc.arrays import LIBRARIES, LUMINANCE, array_ops, array_ops_for
from pgc.errors import PGCConfigError

NP = array_ops("numpy")
TOL = 1e-14
"""float64 agreement between libraries: the measured spread is at most 2.2e-16 (one ulp of values near 1,
the filters' summation order); element-wise calls agree exactly."""


@contextlib.contextmanager
def float64(library: str):
    """JAX computes in float32 unless x64 is enabled (process-wide flag: enabled only inside the test)."""
    if library == "jax":
        import jax

        with jax.enable_x64(True):
            yield
    else:
        yield


@pytest.fixture(params=LIBRARIES)
def ops(request):
    pytest.importorskip(request.param)
    with float64(request.param):
        yield array_ops(request.param)


def gaussian_taps(sigma: float = 1.5, taps: int = 11) -> np.ndarray:
    t = np.arange(taps) - taps // 2
    g = np.exp(-0.5 * t * t / sigma ** 2)
    return g / g.sum()


def test_element_wise_and_vector_calls_agree_with_numpy(ops):
    rng = np.random.default_rng(0)
    a_np, b_np = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    a, b = ops.asarray(a_np, dtype="float64"), ops.asarray(b_np, dtype="float64")
    assert str(a.dtype).endswith("float64")
    expect = {
        "sqrt": (ops.sqrt(ops.xp.abs(a)), np.sqrt(np.abs(a_np))),
        "exp": (ops.exp(a), np.exp(a_np)),
        "maximum": (ops.maximum(a, 0.25), np.maximum(a_np, 0.25)),
        "minimum": (ops.minimum(a, -0.25), np.minimum(a_np, -0.25)),
        "clip": (ops.clip(a, -0.5, 0.5), np.clip(a_np, -0.5, 0.5)),
        "where": (ops.where(a > b, a, 0.0), np.where(a_np > b_np, a_np, 0.0)),
        "norm": (ops.norm(a), np.linalg.norm(a_np, axis=-1)),
        "cross": (ops.cross(a, b), np.cross(a_np, b_np)),
        "luminance": (ops.luminance(a), a_np @ np.array(LUMINANCE)),
        "expand": (ops.expand(ops.norm(a)) * a, np.linalg.norm(a_np, axis=-1)[:, None] * a_np),
        "stack": (ops.stack([a, b], axis=-1), np.stack([a_np, b_np], axis=-1)),
        "concat": (ops.concat([a, b], axis=1), np.concatenate([a_np, b_np], axis=1)),
        "zeros": (ops.zeros((2, 5), like=a), np.zeros((2, 5))),
        "param": (ops.param([0.1, 0.2, 0.3], a) * a, np.array([0.1, 0.2, 0.3]) * a_np),
        "einsum": (ops.xp.einsum("ij,ij->i", a, b), (a_np * b_np).sum(1)),
    }
    for name, (got, want) in expect.items():
        got = ops.to_numpy(got)
        assert got.dtype == np.float64, name
        assert got.shape == want.shape, name
        np.testing.assert_allclose(got, want, rtol=TOL, atol=TOL, err_msg=name)
    x, y, z = ops.split(a)
    np.testing.assert_array_equal(ops.to_numpy(ops.stack([x, y, z], axis=-1)), a_np)
    assert ops.expand(2.0) == 2.0


def test_index_add_sums_repeated_rows_and_leaves_the_input_unchanged(ops):
    a_np = np.arange(8.0).reshape(4, 2)
    a = ops.asarray(a_np, dtype="float64")
    idx = ops.asarray(np.array([0, 2, 0, 0, 3]))
    values = ops.asarray(np.arange(10.0).reshape(5, 2), dtype="float64")
    out = ops.to_numpy(ops.index_add(a, idx, values))
    np.testing.assert_array_equal(out, [[0 + 0 + 4 + 6, 1 + 1 + 5 + 7], [2, 3], [4 + 2, 5 + 3], [6 + 8, 7 + 9]])
    np.testing.assert_array_equal(ops.to_numpy(a), a_np)


def test_loop_runs_the_body_n_times_in_order(ops):
    """Fibonacci with a step counter: the carry is a tuple, the index k is passed in order."""
    zero = ops.asarray(0.0, dtype="float64")

    def body(k, carry):
        f0, f1, ks = carry
        return f1, f0 + f1, ks * 10 + (k + 1)

    f0, f1, ks = ops.loop(6, body, (zero, zero + 1, zero))
    assert (float(f0), float(f1), float(ks)) == (8.0, 13.0, 123456.0)


def test_jax_loop_traces_under_jit():
    jax = pytest.importorskip("jax")
    ops = array_ops("jax")
    f = jax.jit(lambda x: ops.loop(5, lambda k, c: c * 2 + k, x))
    assert float(f(ops.asarray(1.0))) == 58.0  # 1 -> 2 -> 5 -> 12 -> 27 -> 58


@pytest.mark.parametrize("padding", ["zeros", "reflect"])
def test_separable_filter_is_the_2d_correlation(ops, padding):
    """Against the window outer(taps, taps) summed directly over a padded image (zeros, or mirrored with the
    edge repeated); a non-symmetric window checks that it correlates (no flip) along the right axes."""
    rng = np.random.default_rng(1)
    images = rng.uniform(size=(2, 2, 9, 12))
    taps = np.array([0.1, 0.2, 0.6, 0.3, -0.2])
    r = len(taps) // 2
    mode = "constant" if padding == "zeros" else "symmetric"
    padded = np.pad(images, ((0, 0), (0, 0), (r, r), (r, r)), mode=mode)
    window = np.outer(taps, taps)
    want = np.zeros_like(images)
    for i in range(images.shape[2]):
        for j in range(images.shape[3]):
            want[:, :, i, j] = (window * padded[:, :, i:i + len(taps), j:j + len(taps)]).sum((2, 3))
    got = ops.to_numpy(ops.separable_filter(ops.asarray(images, dtype="float64"), taps, padding))
    np.testing.assert_allclose(got, want, rtol=TOL, atol=TOL)


def test_numpy_reflect_filter_is_scipy_gaussian_filter_bit_for_bit():
    """With scipy's taps the numpy filter is ``gaussian_filter(sigma, truncate=3.5, mode='reflect')``."""
    from scipy.ndimage import gaussian_filter

    image = np.random.default_rng(2).uniform(size=(2, 3, 16, 13))
    want = gaussian_filter(image, sigma=(0, 0, 1.5, 1.5), truncate=3.5, mode="reflect")
    np.testing.assert_array_equal(NP.separable_filter(image, gaussian_taps(), "reflect"), want)


def test_separable_filter_gradients():
    """torch: finite differences in float64 (gradcheck); JAX: the same gradient as torch."""
    torch = pytest.importorskip("torch")
    jax = pytest.importorskip("jax")
    rng = np.random.default_rng(3)
    image, weights = rng.uniform(size=(1, 1, 4, 5)), rng.normal(size=(1, 1, 4, 5))
    taps = gaussian_taps(1.0, 5)
    t_ops, j_ops = array_ops("torch"), array_ops("jax")
    for padding in ("zeros", "reflect"):
        x = torch.tensor(image, requires_grad=True)
        assert torch.autograd.gradcheck(lambda a: t_ops.separable_filter(a, taps, padding), (x,))
        (t_ops.separable_filter(x, taps, padding) * torch.tensor(weights)).sum().backward()
        with jax.enable_x64(True):
            g = jax.grad(lambda a: (j_ops.separable_filter(a, taps, padding) * weights).sum())(
                j_ops.asarray(image, dtype="float64"))
        np.testing.assert_allclose(np.asarray(g), x.grad.numpy(), rtol=TOL, atol=TOL)


def test_torch_param_and_asarray_keep_the_graph_dtype_and_device():
    torch = pytest.importorskip("torch")
    ops = array_ops("torch")
    like = torch.zeros(3, dtype=torch.float32)
    p = torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64, requires_grad=True)
    q = ops.param(p, like)
    assert q.dtype == torch.float32 and q.device == like.device
    (q * 2).sum().backward()
    np.testing.assert_array_equal(p.grad.numpy(), [2.0, 2.0, 2.0])
    assert ops.param(0.5, like).dtype == torch.float32
    assert ops.asarray([1, 2], dtype="float64").dtype == torch.float64


def test_one_cached_object_per_library_found_from_its_arrays(ops):
    assert array_ops(ops.name) is ops
    assert array_ops_for(ops.asarray([1.0, 2.0])) is ops
    with pytest.raises(PGCConfigError, match="arrays of numpy, torch, jax"):
        array_ops_for([1.0, 2.0])


def test_bad_requests_are_one_clear_error():
    with pytest.raises(PGCConfigError, match="unknown array library 'cupy'; use one of: numpy, torch, jax"):
        array_ops("cupy")
    with pytest.raises(PGCConfigError, match="padding 'wrap' is not one of zeros, reflect"):
        NP.separable_filter(np.zeros((1, 1, 4, 4)), [1.0], "wrap")
    with pytest.raises(PGCConfigError, match="odd number of taps"):
        NP.separable_filter(np.zeros((1, 1, 4, 4)), [0.5, 0.5])
    with pytest.raises(PGCConfigError, match=r"\(N, C, H, W\) batch of images"):
        NP.separable_filter(np.zeros((4, 4, 1)), [1.0])


def test_importing_the_layer_imports_neither_torch_nor_jax():
    code = ("import sys; import pgc.arrays as a; a.array_ops('numpy'); import pgc.brdfs.maths, pgc.sim.xpbd; "
            "print(','.join(m for m in ('torch', 'jax') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
