"""The synthetic body's motions: a short, coarse version of the penetration criterion (JAX backend).

Criterion: penetration deeper than the 0.4 cm offset stays under 0.5 % of the garment vertices
at the end of every frame. Coarse garments (5 cm edges), 0.4 s of each motion, 10 substeps x 10 iterations.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("scipy")


@pytest.fixture(scope="module")
def body(default_body_model):
    from pgc.synth.body import make_body

    return make_body(default_body_model)


@pytest.mark.slow
@pytest.mark.parametrize("garment,motions", [("tshirt", ("goalpost", "spooky", "arms-up", "arm-swing")),
                                             ("dress", ("walk",))])
def test_synthetic_motions_keep_penetration_under_half_a_percent(body, garment, motions):
    from pgc_jax.xpbd.simulator import JaxXPBDSimulator

    from pgc.synth.garments import make_garment
    from pgc.synth.motions import make_motion

    cloth = make_garment(body, garment, resolution=0.05)
    sim = JaxXPBDSimulator({"substeps": 10, "iterations": 10, "settle_frames": 5})
    for name in motions:
        out = sim.simulate(cloth, make_motion(body, name, seconds=0.4))
        assert np.all(np.isfinite(out.vertices))
        worst = max(out.figures["penetration_fraction"])
        assert worst < 0.005, (name, worst)
        assert max(out.figures["p99_stretch_strain"]) < 0.1, name  # nothing tears or explodes
