"""Spec and options of the synthetic-scene renderer (role ``scene_renderer``, name ``mitsuba``). Light module."""

from pgc.options import Options, count
from pgc.registry import ImplementationSpec


class MitsubaSceneOptions(Options):
    max_depth: int = count(8, 2, 64)
    """Maximum path length of the ``path`` integrator (Mitsuba convention: 2 = direct light only)."""


SPECS = [
    ImplementationSpec(
        role="scene_renderer", name="mitsuba", factory="pgc_mitsuba.synth_scene:MitsubaSceneRenderer",
        description="Mitsuba 3 path tracer (LLVM, CPU) for synthetic captures: colour with a box pixel filter, "
                    "exact ray-cast mask, segmentation, albedo and depth",
        options="pgc_mitsuba.specs_scene:MitsubaSceneOptions", requires=("mitsuba", "drjit"), extra="mitsuba"),
]
