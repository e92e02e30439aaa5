"""Base class of every options schema: validated, immutable, unknown keys rejected, floats finite."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Options(BaseModel):
    """Options of an implementation or a stage. Subclass and declare fields with defaults and docs.

    Every float field rejects ``inf`` and ``nan`` (``allow_inf_nan=False``): a non-finite setting fails at
    ``pgc config validate`` instead of as non-finite results deep inside a run. A schema that means to accept
    them overrides ``model_config``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False)
