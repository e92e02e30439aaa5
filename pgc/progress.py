"""A progress display observing stage events (tqdm on stderr)."""

from __future__ import annotations

import sys
import weakref
from typing import Any

from pgc.hookspecs import hookimpl


class ProgressPrinter:
    """Shows a bar per stage with its figures, and a line with the time when it finishes."""

    _live: "weakref.WeakSet[ProgressPrinter]" = weakref.WeakSet()

    def __init__(self, stream: Any = None) -> None:
        self._stream = stream
        self._bars: dict[str, Any] = {}
        ProgressPrinter._live.add(self)

    @property
    def stream(self) -> Any:
        """The stream given, else the current ``sys.stderr``; a closed one (an embedding program or test harness
        replaced and closed it) falls back to the process's original stderr, so progress never fails a run."""
        stream = self._stream if self._stream is not None else sys.stderr
        return sys.__stderr__ if getattr(stream, "closed", False) else stream

    def close(self) -> None:
        """Close the bars of stages that never finished (a command that failed or was interrupted): tqdm keeps
        every open bar and redraws it when a later bar starts, which would write to a stream gone by then."""
        for bar in self._bars.values():
            bar.close()
        self._bars.clear()

    @classmethod
    def close_all(cls) -> None:
        """:meth:`close` every printer of this process (the command line calls it when a command ends)."""
        for printer in list(cls._live):
            printer.close()

    @hookimpl
    def pgc_stage_started(self, stage: str, info: dict[str, Any]) -> None:
        from tqdm import tqdm

        total = info.get("total")
        self._bars[stage] = tqdm(total=total, desc=stage, file=self.stream, leave=False, dynamic_ncols=True,
                                 disable=None)

    @hookimpl
    def pgc_stage_progress(self, stage: str, done: int, total: int | None, figures: dict[str, float]) -> None:
        bar = self._bars.get(stage)
        if bar is None:
            return
        if total is not None and bar.total != total:
            bar.total = total
        bar.update(done - bar.n)
        if figures:
            bar.set_postfix({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in figures.items()},
                            refresh=False)

    @hookimpl
    def pgc_stage_finished(self, stage: str, seconds: float, figures: dict[str, Any]) -> None:
        bar = self._bars.pop(stage, None)
        if bar is not None:
            bar.close()
        shown = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                          for k, v in figures.items() if isinstance(v, (int, float, str)))
        print(f"[{stage}] {seconds:.1f} s" + (f"  {shown}" if shown else ""), file=self.stream)
