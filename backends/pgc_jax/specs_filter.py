"""Registration of the JAX ``filter`` (light: pgc core and pydantic only)."""

from __future__ import annotations

from pgc.options import Options
from pgc.registry import ImplementationSpec


class JaxFilterOptions(Options):
    """No options: the blur runs on JAX's default device in float32."""


SPECS = [
    ImplementationSpec(
        role="filter", name="jax", factory="pgc_jax.filter:JaxFilter",
        description="alpha-aware Gaussian low-pass, separable depthwise convolution in JAX/XLA (jit, differentiable)",
        options="pgc_jax.specs_filter:JaxFilterOptions", requires=("jax",), extra="jax"),
]
