"""The pipeline's stages, one declaration each (``pgc/stages/<name>.py``: name, role, settings, version, inputs,
outputs; :class:`~pgc.stages.declaration.Stage`). Light to import: :func:`declared` loads the declarations
(and their settings models) only when asked, as when a config is resolved."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pgc.options import Options
    from pgc.stages.declaration import Stage


def declared() -> dict[str, Stage]:
    """Every stage by name, in pipeline order."""
    from pgc.stages import animate, base_color, body_fit, fit_splats, garment, material, mesh, render
    from pgc.stages import eval as evaluate

    return {s.STAGE.name: s.STAGE for s in (mesh, garment, fit_splats, base_color, material, body_fit, animate, render, evaluate)}


def settings_models() -> dict[str, type[Options]]:
    """Stage name -> its ``[stages.NAME]`` options model, for every stage that has one."""
    return {name: stage.settings for name, stage in declared().items() if stage.settings is not None}


PIPELINE_COLUMNS = ("stage", "command", "config table", "role", "key roles", "version", "inputs", "outputs", "folder")
"""The columns of the stage table in docs/pipeline.md."""


def stage_table(columns: tuple[str, ...] = PIPELINE_COLUMNS) -> list[str]:
    """The markdown table of the declared stages (the docs' stage tables are checked against it)."""
    cells = {
        "stage": lambda s: s.name,
        "command": lambda s: f"`pgc {s.command}`",
        "config table": lambda s: f"`{s.config_table}`",
        "role": lambda s: f"`{s.role}`" if s.role else "-",
        "key roles": lambda s: ", ".join(f"`{r}`" if n is None else f"`{r}` (`{n}`)"
                                         for r, n in s.key_roles(s.settings() if s.settings else None).items()) or "-",
        "settings": lambda s: (f"`{s.settings.__module__}.{s.settings.__qualname__}`" if s.settings
                               else f"the {s.role}'s options"),
        "version": lambda s: s.version if s.cached else f"{s.version} (not cached)",
        "inputs": lambda s: ", ".join(f"`{i}`" for i in s.inputs),
        "outputs": lambda s: ", ".join(f"`{o}`" for o in s.outputs),
        "folder": lambda s: f"`{s.folder}`",
        "progress events": lambda s: ", ".join(f"`{e}`" for e in s.events) or "-",
    }
    rows = [" | ".join(columns), " | ".join("---" for _ in columns)]
    rows += [" | ".join(cells[c](s) for c in columns) for s in declared().values()]
    return [f"| {r} |" for r in rows]
