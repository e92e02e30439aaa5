"""Options of the ``animate`` stage (the simulation of the garment on a body motion)."""

from pydantic import Field

from pgc.options import Options

MAX_SECONDS = 600.0
"""Longest simulated motion (seconds)."""


class AnimateSettings(Options):
    seconds: float | None = Field(None, gt=0, le=MAX_SECONDS, description=(
        f"motion length in (0, {MAX_SECONDS}] seconds; None: the motion's own length"))

