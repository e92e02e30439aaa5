"""A progress display observing stage events (tqdm on stderr)."""

from __future__ import annotations

import sys
from typing import Any

from pgc.hookspecs import hookimpl


class ProgressPrinter:
    """Shows a bar per stage with its figures, and a line with the time when it finishes."""

    def __init__(self, stream: Any = None) -> None:
        self.stream = stream or sys.stderr
        self._bars: dict[str, Any] = {}

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
