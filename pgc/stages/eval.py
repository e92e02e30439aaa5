"""Stage ``eval``: metrics of every rendered variant against ground truth. Computed on every run (its ground
truth renders are cached under ``RUN/gt/<key>``, :func:`pgc.pipeline.evaluate.ground_truth_key`)."""

from pgc.options import Options, count
from pgc.stages.declaration import Stage


class EvalSettings(Options):
    gt_spp: int = count(64, 1, 65536, "path-tracing samples of the ground-truth renders")


STAGE = Stage(name="eval", command="eval", version="1", inputs=("render", "ground_truth"), outputs=("metrics.json",),
              folder="RUN/metrics.json", role="metric", roles=("metric", "scene_renderer"), settings=EvalSettings,
              events=("render_gt_frames", "eval"), cached=False)
