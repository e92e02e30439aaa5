"""Registration of ``xpbd-native`` (light: pgc core and pydantic only; the kernel is built on first use)."""

from __future__ import annotations

from pydantic import Field

from pgc.registry import ImplementationSpec
from pgc.sim.options import XPBDOptions


class NativeXPBDOptions(XPBDOptions):
    """:class:`~pgc.sim.options.XPBDOptions` plus the kernel's thread count (results do not depend on it)."""

    threads: int = Field(1, ge=0, description="OpenMP threads of the frame kernel; 0 = all CPU cores. The result "
                         "is the same, byte for byte, for any count. Default 1: a frame has ~20 barriers per "
                         "iteration, which pay only on idle cores (measured on 2 shared cores: 2 threads 1.2-70x "
                         "slower than 1, docs/simulation.md)")
    simd: bool = Field(True, description="run the AVX-512 build of the kernel where the CPU has it (else the "
                       "baseline build); both give the same bytes")


SPECS = [
    ImplementationSpec(
        role="simulator", name="xpbd-native", factory="pgc_native.xpbd.simulator:NativeXPBDSimulator",
        description="XPBD cloth (the xpbd-jax maths) as one compiled C++/OpenMP call per frame; deterministic",
        options="pgc_native.specs_xpbd:NativeXPBDOptions", requires=("scipy",)),
]
