"""Stage ``eval``: metrics of every rendered variant against ground truth. Computed on every run (its ground
truth renders are cached under ``RUN/gt/<key>``, :func:`pgc.pipeline.evaluate.ground_truth_key`)."""

from typing import Any

from pydantic import Field

from pgc.options import Options, count
from pgc.stages.declaration import Stage

MODES = ("appearance", "independent")
"""Evaluation modes (pgc eval --mode): the truth on the run's simulated geometry, or simulated on its own
(:mod:`pgc.pipeline.independent`)."""


class EvalSettings(Options):
    gt_spp: int = count(64, 1, 65536, "path-tracing samples of one pass of a ground-truth render")
    gt_noise: float = Field(0.04, ge=0.0, lt=1.0, description=(
        "the ground truth's largest relative Monte Carlo noise (rms standard error over the garment's pixels / "
        "their mean): passes of gt_spp samples are added until a view reaches it or gt_max_spp; 0: one pass "
        "(why: docs/synth.md, 'Converged truth')"))
    gt_max_spp: int = count(1024, 1, 65536, "samples a ground-truth view may spend to reach gt_noise")
    truth_simulator: str = Field("newton-vbd", description="independent mode (pgc eval --mode independent): the "
                                 "simulator of the truth garment, with its own default options")
    truth_resolution: float = Field(2.0, ge=1.0, le=4.0, description="independent mode: the truth rest garment's "
                                    "edges are this many times shorter than the capture garment's")
    truth_options: dict[str, Any] = Field(default_factory=dict, description="independent mode: options of the "
                                          "truth simulator over its defaults (empty: its own cloth)")


STAGE = Stage(name="eval", command="eval", version="3", inputs=("render", "ground_truth"), outputs=("metrics.json",),
              folder="RUN/metrics.json", role="metric", roles=("metric", "scene_renderer"), settings=EvalSettings,
              events=("render_gt_frames", "eval"), cached=False)
