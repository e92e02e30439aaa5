"""Shared base of role implementations."""

from __future__ import annotations

import functools
from typing import Any, Callable, ClassVar

from pgc.options import Options

InputCheck = Callable[[Callable[..., Any]], Callable[..., Any]]
"""Takes a method and returns a function of the same arguments that checks them, then calls the method."""


class RoleImplementation:
    """Holds validated options. ``role`` names the role; subclasses set ``Options``.

    A role checks the inputs of its public methods once, for every implementation: it maps each such method's
    name to an :data:`InputCheck` in ``input_checks``, and each implementation's own definition of the method
    is wrapped by it when the class is created (a definition already wrapped, or abstract, is left alone)."""

    role: ClassVar[str] = ""
    Options: ClassVar[type[Options]] = Options
    input_checks: ClassVar[dict[str, InputCheck]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        for name, check in cls.input_checks.items():
            method = cls.__dict__.get(name)
            if callable(method) and not getattr(method, "__isabstractmethod__", False) \
                    and not getattr(method, "inputs_checked", False):
                checked = functools.wraps(method)(check(method))
                checked.inputs_checked = True  # type: ignore[attr-defined]
                setattr(cls, name, checked)

    def __init__(self, options: Options | dict[str, Any] | None = None) -> None:
        if options is None or isinstance(options, dict):
            options = self.Options.model_validate(options or {})
        self.options = options
