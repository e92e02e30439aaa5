"""One runner for every command's list of stages: cache keys derived from the declarations, caching, timing.

A command builds a :class:`StageRunner` over its stage cache, the keys of its :data:`~pgc.stages.declaration.SOURCES`
and its inputs, then runs its stages in order, each with the :class:`Step` that computes and loads it. A
stage's key (:meth:`StageRunner.key`) hashes exactly what its declaration names: the output files of its
upstream stages, the keys of its sources, the choice of its roles (``RunConfig.role_key``; with
``fingerprint_roles`` the implementation's ``fingerprint``), its settings and its version. So a changed
setting, role or version recomputes that stage and, through its changed outputs, the stages that read them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Generic, TypeVar

from pgc.config import RunConfig
from pgc.events import Reporter
from pgc.io.timings import split_timings
from pgc.pipeline.cache import StageCache, StageResult, content_key
from pgc.stages.declaration import Stage

I = TypeVar("I")


@dataclass
class StageContext(Generic[I]):
    """What a stage's code receives: the configuration, the reporter, the command's inputs and the values of the
    stages run before it."""

    cfg: RunConfig
    reporter: Reporter
    inputs: I
    values: dict[str, Any] = field(default_factory=dict)
    _implementations: dict[str, Any] = field(default_factory=dict, init=False, repr=False)

    def implementation(self, role: str) -> Any:
        """The configured implementation of ``role``, created once per run."""
        if role not in self._implementations:
            self._implementations[role] = self.cfg.create(role)
        return self._implementations[role]


@dataclass(frozen=True)
class Step(Generic[I]):
    """The code of one stage: ``compute(ctx, folder) -> (value, figures)`` writes the declared outputs into
    ``folder``; ``load(ctx, folder) -> value`` reads them back (cached stages only)."""

    compute: Callable[[StageContext[I], Path], tuple[Any, dict[str, Any]]]
    load: Callable[[StageContext[I], Path], Any] | None = None


class StageRunner(Generic[I]):
    """Runs declared stages through one stage cache, recording each stage's seconds (0 when reused)."""

    def __init__(self, cache: StageCache, ctx: StageContext[I], sources: dict[str, Any]) -> None:
        self.cache = cache
        self.ctx = ctx
        self.sources = sources
        self.seconds: dict[str, float] = {}
        self.ran: list[Stage] = []

    def key(self, stage: Stage) -> str:
        """The stage's cache key, from its declaration (see the module docstring)."""
        settings = self.ctx.cfg.stage(stage.name) if stage.settings is not None else None
        inputs = {}
        for name in stage.inputs:
            if name in self.sources:
                inputs[name] = self.sources[name]
            elif any(s.name == name for s in self.ran):
                inputs[name] = self.cache.output_key(name)
            else:
                raise KeyError(f"stage '{stage.name}' reads '{name}', which is neither a source given to the runner "
                               f"({', '.join(self.sources)}) nor a stage it ran")
        roles = {role: self.ctx.cfg.role_key(role, name) for role, name in stage.key_roles(settings).items()}
        fingerprints = {role: getattr(self.ctx.implementation(role), "fingerprint", None)
                        for role in stage.fingerprint_roles}
        return content_key(stage.name, stage.version, inputs, roles, fingerprints, settings)

    def run(self, stage: Stage, step: Step[I]) -> Any:
        """Compute ``stage`` (or, when cached under its key, load it); its value is kept in ``ctx.values``."""
        if stage.cached and step.load is None:
            raise TypeError(f"stage '{stage.name}' is cached: its step needs a load function")
        key = self.key(stage) if stage.cached else None
        start = time.perf_counter()
        if key is not None:
            ctx = self.ctx
            result: StageResult = self.cache.run(stage.name, key,
                                                 lambda folder: self._compute(stage, step, folder),
                                                 lambda folder: step.load(ctx, folder), stage.version)
            value, reused = result.value, result.cached
        else:
            value, _ = step.compute(self.ctx, self.cache.root)
            reused = False
        self.seconds[stage.name] = self.seconds.get(stage.name, 0.0) + (
            0.0 if reused else time.perf_counter() - start)
        self.ctx.values[stage.name] = value
        self.ran.append(stage)
        return value

    def _compute(self, stage: Stage, step: Step[I], folder: Path) -> tuple[Any, dict[str, Any]]:
        value, figures = step.compute(self.ctx, folder)
        missing = [pattern for pattern in stage.outputs if not any(folder.glob(pattern))]
        if missing:
            raise RuntimeError(f"stage '{stage.name}' did not write its declared outputs {missing} into {folder}")
        return value, figures

    def figures(self) -> tuple[dict[str, Any], dict[str, Any] | None]:
        """``(figures, timings)`` recorded by the cached stages run so far (:func:`pgc.io.timings.split_timings`)."""
        return split_timings({s.name: self.cache.figures(s.name) for s in self.ran if s.cached})
