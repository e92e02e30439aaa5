"""Cross-backend agreement: the torch and JAX splat renderers, built through the registry, on the same scenes."""

from __future__ import annotations

import numpy as np
import pytest

from pgc.registry import default_registry
from pgc.splats.reference import render_reference
from pgc.types import Camera, WorldGaussians


def _renderers():
    impls = {i.name: i for i in default_registry().list("splat_renderer")}
    missing = [n for n in ("torch", "jax") if n not in impls or not impls[n].available]
    if missing:
        pytest.fail(f"splat_renderer implementations not available: {missing}")
    return impls["torch"].create(), impls["jax"].create()


@pytest.mark.agreement
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_torch_and_jax_images_agree_with_each_other_and_the_reference(seed):
    rng = np.random.default_rng(seed)
    n = 150
    means = np.c_[rng.uniform(-0.35, 0.35, n), rng.uniform(-0.25, 0.25, n), rng.uniform(0.8, 1.6, n)]
    world = WorldGaussians(means, rng.normal(size=(n, 4)), rng.uniform(0.01, 0.1, (n, 3)), rng.uniform(0.05, 1, n),
                           rng.normal(0, 0.4, (n, 16, 3)))
    cam = Camera(K=[[38, 0, 16.5], [0, 40, 11.7], [0, 0, 1]], R=np.eye(3), t=[0.01, 0, 0.05], width=32, height=24)
    bg = rng.uniform(size=(24, 32, 3))
    torch_r, jax_r = _renderers()
    ref = render_reference(world, cam, background=bg)
    a, b = torch_r.render(world, cam, bg), jax_r.render(world, cam, bg)
    for out in (a, b):
        np.testing.assert_allclose(out.color, ref.color, atol=1e-5)
        np.testing.assert_allclose(out.alpha, ref.alpha, atol=1e-5)
    np.testing.assert_allclose(a.color, b.color, atol=1e-5)
    np.testing.assert_allclose(a.depth, b.depth, rtol=1e-5, atol=2e-5)
