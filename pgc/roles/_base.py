"""Shared base of role implementations."""

from __future__ import annotations

from typing import Any, ClassVar

from pgc.options import Options


class RoleImplementation:
    """Holds validated options. ``role`` names the role; subclasses set ``Options``."""

    role: ClassVar[str] = ""
    Options: ClassVar[type[Options]] = Options

    def __init__(self, options: Options | dict[str, Any] | None = None) -> None:
        if options is None or isinstance(options, dict):
            options = self.Options.model_validate(options or {})
        self.options = options
