"""Options of the ``eval`` stage (metrics of every rendered variant against ground truth)."""

from pgc.options import Options, count


class EvalSettings(Options):
    gt_spp: int = count(64, 1, 65536, "path-tracing samples of the ground-truth renders")

