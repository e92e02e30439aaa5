"""What a pipeline stage is: :class:`Stage`, declared once per stage in ``pgc/stages/<name>.py``.

A declaration names the stage, the role it calls, its settings (the ``[stages.NAME]`` table), the version of
the code that computes it, what it reads (``inputs``: upstream stages of the same command or the
:data:`SOURCES`), the roles whose choice decides its result, and the files it writes. The pipeline derives a
stage's cache key from these alone (:class:`pgc.pipeline.runner.StageRunner`) and binds the code that computes
and loads it (:data:`pgc.pipeline.runner.Step`); the configuration validates ``[stages.NAME]`` through them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable

from pgc.options import Options

if TYPE_CHECKING:
    from pgc.config import RoleChoice

SOURCES: dict[str, str] = {
    "capture": "the capture folder's files",
    "garment_labels": "the capture's garment label ids",
    "asset": "the asset folder (the files and held-out views its manifest records)",
    "motion": "the body motion (its name or file, vertices, faces and frame rate)",
    "run": "the run's simulated garment (RUN/garment.npz)",
    "light": "the light the frames are rendered under (radiance, environment map, rotation, file)",
    "ground_truth": "the synthetic capture or image folder the frames are compared with",
}
"""Inputs that are not a stage's output: what a command is given, by name (a stage's ``inputs`` entry)."""

COMMANDS = ("reconstruct", "animate", "render", "eval")
"""The commands that run stages, in pipeline order."""

SettingsCheck = Callable[[Options, dict[str, Any], "dict[str, RoleChoice]", str], Options]
"""``check(settings, given, roles, source) -> settings``: a stage's own rule over its validated settings,
``given`` (the table as written in the config) and the chosen roles; returns the settings to run with or
raises :class:`pgc.errors.PGCConfigError` naming ``source``."""


@dataclass(frozen=True)
class Stage:
    """The declaration of one pipeline stage (its cache key is derived from it, see the module docstring)."""

    name: str
    command: str
    """The command that runs it (one of :data:`COMMANDS`)."""
    version: str
    """Version of the code computing it, part of its cache key: raise it when that code changes what the stage
    computes, so no run reuses a result made by older code."""
    inputs: tuple[str, ...]
    """What it reads: names of earlier stages of the same command (their output files' hash enters the key) or
    of :data:`SOURCES`."""
    outputs: tuple[str, ...]
    """Files it writes into its folder (glob patterns where it writes several)."""
    folder: str
    """Where its result lives, relative to the command's output (``ASSET/stages/mesh``, ``RUN/render``)."""
    role: str | None = None
    """The role whose work it is (None: none, as ``garment``, or several, as ``render``: see ``roles``)."""
    roles: tuple[str, ...] = ()
    """Roles whose choice (implementation, options, version) enters the cache key; default ``(role,)``."""
    settings: type[Options] | None = None
    """Its ``[stages.NAME]`` options model (None: it has none; its role's options configure it)."""
    settings_roles: Callable[[Any], dict[str, str]] | None = None
    """Implementations that enter the key only under some settings: ``settings -> {role: implementation}`` (one
    implementation of a multi role, as the kernel rule's metric, not the role's whole list)."""
    fingerprint_roles: tuple[str, ...] = ()
    """Roles whose created implementation's ``fingerprint`` (e.g. model weights) enters the key."""
    check: SettingsCheck | None = None
    """Its own rule over its settings and the chosen roles, applied when a config is resolved."""
    events: tuple[str, ...] = ()
    """The progress events (:meth:`pgc.events.Reporter.stage`) it reports."""
    cached: bool = True
    """Whether it is stored by content key (an uncached stage is computed on every run)."""

    def key_roles(self, settings: Any) -> dict[str, str | None]:
        """The roles whose choice enters the cache key under ``settings``: role -> the implementation that counts
        (None: the role's chosen one, the first of a multi role)."""
        base = self.roles or ((self.role,) if self.role else ())
        return {**dict.fromkeys(base), **(self.settings_roles(settings) if self.settings_roles else {})}

    @property
    def config_table(self) -> str:
        """The config table that configures it."""
        if self.settings is not None:
            return f"[stages.{self.name}]"
        return f"[{self.role}]" if self.role else "-"
