"""Registration of ``xpbd-torch`` (light: pgc core only)."""

from __future__ import annotations

from pgc.registry import ImplementationSpec

SPECS = [
    ImplementationSpec(
        role="simulator", name="xpbd-torch", factory="pgc_torch.xpbd.simulator:TorchXPBDSimulator",
        description="XPBD cloth (stretch + bending springs, body collision with friction) in PyTorch, eager",
        options="pgc.sim.options:XPBDOptions", requires=("torch", "scipy"), extra="torch"),
]
