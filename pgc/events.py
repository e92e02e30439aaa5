"""Stage events: timing and progress reported through the pluggy event hooks.

Producers call :class:`Reporter` (``with reporter.stage("fit_splats", iterations=3000) as s: s.progress(...)``);
observers (progress bar, logger, benchmark recorder) implement the ``pgc_stage_*`` hooks.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field
from typing import Any, Iterator


@dataclass
class StageHandle:
    """Reports progress and figures of one running stage."""

    name: str
    _hook: Any
    total: int | None = None
    figures: dict[str, Any] = field(default_factory=dict)
    done: int = 0

    def progress(self, done: int, total: int | None = None, **figures: float) -> None:
        self.done = done
        if total is not None:
            self.total = total
        if self._hook is not None:
            self._hook.pgc_stage_progress(stage=self.name, done=done, total=self.total, figures=dict(figures))

    def record(self, **figures: Any) -> None:
        """Attach measured figures to the stage's 'finished' event."""
        self.figures.update(figures)


class Reporter:
    """Emits stage events to the hooks of a registry's plugin manager (or nowhere when ``hook`` is None)."""

    def __init__(self, hook: Any = None) -> None:
        self._hook = hook
        self.timings: dict[str, float] = {}

    @classmethod
    def silent(cls) -> "Reporter":
        return cls(None)

    @contextlib.contextmanager
    def stage(self, name: str, total: int | None = None, **info: Any) -> Iterator[StageHandle]:
        handle = StageHandle(name, self._hook, total)
        if self._hook is not None:
            self._hook.pgc_stage_started(stage=name, info=dict(info, total=total))
        start = time.perf_counter()
        yield handle
        seconds = time.perf_counter() - start
        self.timings[name] = self.timings.get(name, 0.0) + seconds
        if self._hook is not None:
            self._hook.pgc_stage_finished(stage=name, seconds=seconds, figures=dict(handle.figures))
