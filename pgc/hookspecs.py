"""The pluggy hook specifications: the contract between PGC and its plugins.

A plugin is a module named by an entry point of the group ``pgc``. It implements
:func:`pgc_register_implementations` to declare what it provides (cheap :class:`ImplementationSpec`
objects; nothing heavy is imported) and may implement the event hooks to observe runs.
Event hooks are observers: their return values are ignored and they must not mutate their arguments.
"""

from __future__ import annotations

from typing import Any

import pluggy

PROJECT = "pgc"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def pgc_register_implementations() -> list:  # list[ImplementationSpec]
    """Return the implementations this plugin provides, as ``pgc.registry.ImplementationSpec`` objects."""


@hookspec
def pgc_stage_started(stage: str, info: dict[str, Any]) -> None:
    """A pipeline stage (or a long computation) starts. ``info``: settings worth showing."""


@hookspec
def pgc_stage_progress(stage: str, done: int, total: int | None, figures: dict[str, float]) -> None:
    """A stage advanced to ``done`` of ``total`` steps; ``figures`` are current measurements (loss, PSNR)."""


@hookspec
def pgc_stage_finished(stage: str, seconds: float, figures: dict[str, Any]) -> None:
    """A stage finished after ``seconds`` of wall time with its measured ``figures``."""
