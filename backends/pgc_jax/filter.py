"""Alpha-aware low-pass in JAX: two depthwise 1-D convolutions (O(k) per pixel), jit-compiled, differentiable.

``alpha_lowpass`` works on JAX arrays (jit per shape and kernel size); :class:`JaxFilter` is the ``filter``
role implementation (numpy in, numpy out).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from pgc.filtering.kernel import check_kernel_size, gaussian_kernel_1d, renormalise
from pgc.roles.filter import Filter
from pgc_jax.specs_filter import JaxFilterOptions


@partial(jax.jit, static_argnames=("kernel_size",))
def _lowpass(image: jax.Array, alpha: jax.Array, kernel_size: int) -> jax.Array:
    channels = image.shape[-1] + 1
    stack = jnp.concatenate([image * alpha[..., None], alpha[..., None]], axis=-1)[None]  # (1, H, W, C + 1)
    taps = jnp.asarray(gaussian_kernel_1d(kernel_size), dtype=image.dtype)
    r = kernel_size // 2
    dims = ("NHWC", "HWIO", "NHWC")
    x = jax.lax.conv_general_dilated(stack, jnp.tile(taps.reshape(1, -1, 1, 1), (1, 1, 1, channels)),
                                     (1, 1), ((0, 0), (r, r)), dimension_numbers=dims,
                                     feature_group_count=channels)
    x = jax.lax.conv_general_dilated(x, jnp.tile(taps.reshape(-1, 1, 1, 1), (1, 1, 1, channels)),
                                     (1, 1), ((r, r), (0, 0)), dimension_numbers=dims,
                                     feature_group_count=channels)[0]
    return renormalise(x[..., :-1], x[..., -1:], image)


def alpha_lowpass(image: jax.Array, alpha: jax.Array, kernel_size: int) -> jax.Array:
    """Alpha-aware Gaussian low-pass of ``image`` (H, W, C) weighted by ``alpha`` (H, W); same dtype.

    Blurs ``[alpha * image, alpha]`` with zero borders in two passes and renormalises (see
    :func:`pgc.filtering.kernel.renormalise`). Differentiable in ``image`` and ``alpha``.
    """
    return _lowpass(image, alpha, check_kernel_size(kernel_size))


class JaxFilter(Filter):
    """``filter`` 'jax': float32 separable convolution through XLA."""

    Options = JaxFilterOptions

    def lowpass(self, image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
        out = alpha_lowpass(jnp.asarray(image), jnp.asarray(alpha), kernel_size)
        return np.asarray(out, dtype=np.float32)
