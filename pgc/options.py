"""Base class of every options schema: validated, immutable, unknown keys rejected."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Options(BaseModel):
    """Options of an implementation or a stage. Subclass and declare fields with defaults and docs."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)
