"""Options of the ``eval`` stage (metrics of every rendered variant against ground truth)."""

from pydantic import Field

from pgc.options import Options


class EvalSettings(Options):
    gt_spp: int = Field(64, ge=1, description="path-tracing samples of the ground-truth renders")

