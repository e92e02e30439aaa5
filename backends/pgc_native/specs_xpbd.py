"""Registration of ``xpbd-native`` (light: pgc core and pydantic only; the kernel is built on first use)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from pgc.options import MAX_THREADS
from pgc.registry import ImplementationSpec
from pgc.sim.options import XPBDOptions


class NativeXPBDOptions(XPBDOptions):
    """:class:`~pgc.sim.options.XPBDOptions` plus the kernel's thread count (results do not depend on it)."""

    threads: Literal["auto"] | Annotated[int, Field(ge=0, le=MAX_THREADS)] = Field(
        "auto", description="OpenMP threads of the frame kernel; 0 = all allotted cores; 'auto' = whichever of all "
        "allotted cores and 1 thread the frames themselves time as faster, re-timed every 20 frames (a frame has "
        "~20 barriers per iteration: on 2 idle cores 2 threads are 1.6x faster, with one other busy process 3x "
        "slower; docs/simulation.md). The result is the same, byte for byte, for any count")
    simd: bool = Field(True, description="run the AVX-512 build of the kernel where the CPU has it (else the "
                       "baseline build); both give the same bytes")


SPECS = [
    ImplementationSpec(
        role="simulator", name="xpbd-native", factory="pgc_native.xpbd.simulator:NativeXPBDSimulator",
        description="XPBD cloth (the xpbd-jax maths) as one compiled C++/OpenMP call per frame; deterministic",
        options="pgc_native.specs_xpbd:NativeXPBDOptions", requires=("scipy",)),
]
