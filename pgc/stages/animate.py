"""Stage ``animate``: the simulation of the asset's garment on a body motion."""

from pydantic import Field

from pgc.options import Options
from pgc.stages.declaration import Stage

MAX_SECONDS = 600.0
"""Longest simulated motion (seconds)."""


class AnimateSettings(Options):
    seconds: float | None = Field(None, gt=0, le=MAX_SECONDS, description=(
        f"motion length in (0, {MAX_SECONDS}] seconds; None: the motion's own length"))


STAGE = Stage(name="animate", command="animate", version="2", inputs=("asset", "motion"), outputs=("garment.npz",),
              folder="RUN/stages/animate", role="simulator", settings=AnimateSettings,
              events=("sag_free", "animate"))
