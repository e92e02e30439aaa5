"""Base class of every options schema: validated, immutable, unknown keys rejected, floats finite, integers
whole and bounded."""

from __future__ import annotations

import numbers
import types
import typing
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

MAX_INT = 2**31 - 1
"""Largest magnitude of an integer option that declares no upper bound of its own (``le``/``lt``)."""
MAX_SEED = 2**32 - 1
"""Largest random seed (what numpy's and torch's generators take)."""
MAX_THREADS = 1024
"""Most threads an implementation option may ask for."""


def count(default: int | None, ge: int, le: int, description: str = "") -> Any:
    """A bounded integer field ``ge <= value <= le`` (the range is appended to ``description``)::

        iterations: int = count(3000, 1, 1_000_000, "most optimiser steps")
    """
    text = f"{description}; " if description else ""
    return Field(default, ge=ge, le=le, description=f"{text}an integer in [{ge}, {le}]")


def seed_field(default: int = 0, description: str = "random seed") -> Any:
    """A random seed field in ``[0, MAX_SEED]``."""
    return count(default, 0, MAX_SEED, description)


class Options(BaseModel):
    """Options of an implementation or a stage. Subclass and declare fields with defaults and docs.

    Every float field rejects ``inf`` and ``nan`` (``allow_inf_nan=False``): a non-finite setting fails at
    ``pgc config validate`` instead of as non-finite results deep inside a run. A schema that means to accept
    them overrides ``model_config``.

    Every integer field (``int``, ``int | None``, ``list[int]``) takes integers only: ``true`` is not 1 and
    ``3.0`` or ``1e30`` is not an integer. Its value must lie in the field's declared range (:func:`count`), or
    within +-:data:`MAX_INT` when the field declares no upper bound; the error names the allowed range.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _whole_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        field = cls.model_fields.get(info.field_name or "")
        kind = _integer_kind(field.annotation) if field is not None else None
        if kind is None or value is None:
            return value
        low, high = _bounds(field.metadata)
        if kind == "list" and isinstance(value, (list, tuple)):
            for item in value:
                _check_integer(item, low, high, "every item: ")
        elif kind == "int":
            _check_integer(value, low, high)
        return value


def _check_integer(value: Any, low: int, high: int, what: str = "") -> None:
    """Refuse booleans, strings, floats (even whole ones) and integers outside ``[low, high]``; other types are
    left to pydantic (whose message names the type)."""
    wrong = {bool: "a boolean is not an integer", str: "a string is not an integer: write it without quotes"}
    if isinstance(value, numbers.Real) and not isinstance(value, numbers.Integral):
        wrong[type(value)] = "a float is not an integer: write it without a decimal point or exponent"
    problem = wrong.get(type(value)) or ("out of range" if isinstance(value, numbers.Integral)
                                         and not low <= int(value) <= high else None)
    if problem:
        raise PydanticCustomError("integer_option", "{what}Input should be a valid integer in [{low}, {high}] "
                                  "({problem})", {"what": what, "low": low, "high": high, "problem": problem})


def _integer_kind(annotation: Any) -> str | None:
    """'int' for ``int`` (also optional or annotated), 'list' for a list or tuple of ints, else None."""
    while typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    if annotation is int:
        return "int"
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        kinds = {_integer_kind(a) for a in args if a is not type(None)}
        others = [a for a in args if a is not type(None)]
        return kinds.pop() if len(kinds) == 1 and len(others) == 1 else None
    if origin in (list, tuple) and args and all(a is int or a is Ellipsis for a in args):
        return "list"
    return None


def _bounds(metadata: list[Any]) -> tuple[int, int]:
    """The inclusive integer range declared by a field's constraints (``ge``, ``gt``, ``le``, ``lt``)."""
    low, high = -MAX_INT, MAX_INT
    for m in metadata:
        if getattr(m, "ge", None) is not None:
            low = int(m.ge)
        if getattr(m, "gt", None) is not None:
            low = int(m.gt) + 1
        if getattr(m, "le", None) is not None:
            high = int(m.le)
        if getattr(m, "lt", None) is not None:
            high = int(m.lt) - 1
    return low, high
