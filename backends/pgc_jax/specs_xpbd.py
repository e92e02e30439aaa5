"""Registration of ``xpbd-jax`` (light: pgc core only)."""

from __future__ import annotations

from pgc.registry import ImplementationSpec

SPECS = [
    ImplementationSpec(
        role="simulator", name="xpbd-jax", factory="pgc_jax.xpbd.simulator:JaxXPBDSimulator",
        description="XPBD cloth (stretch + bending springs, body collision with friction) in JAX, one jitted frame",
        options="pgc.sim.options:XPBDOptions", requires=("jax", "scipy"), extra="jax"),
]
