"""Options of the ``animate`` stage (the simulation of the garment on a body motion)."""

from pydantic import Field

from pgc.options import Options


class AnimateSettings(Options):
    seconds: float | None = Field(None, gt=0, description="motion length; None: the motion's own length")

