"""One workload per role: a small scene, the role's reference measured in the same run, and errors.

Each module has ``bench(ctx: Context) -> list[dict]`` returning records (:func:`pgc.bench.records.make_record`);
a record may carry ``"_detail"`` (per-view/per-frame data) that the runner writes to a file beside bench.json.
"""

from __future__ import annotations

import traceback
from dataclasses import dataclass
from typing import Any, Callable

from pgc.bench.matrix import Run, expand
from pgc.bench.records import make_record


@dataclass
class Context:
    """What a workload needs: the preset, its parameters, the runs of the matrix and shared inputs."""

    role: str
    preset: str
    params: dict[str, Any]
    runs: list[Run]
    registry: Any
    versions: dict[str, str]
    capture_dir: Callable[[], str]
    """The synthetic capture's folder (generated on first use, cached in the output folder)."""
    stage: Any
    """The role's progress handle (:meth:`pgc.events.Reporter.stage`); :meth:`tick` after each run."""
    done: int = 0

    def param(self, key: str, default: Any) -> Any:
        return self.params.get(key, default)

    def tick(self, **figures: float) -> None:
        self.done += 1
        self.stage.progress(self.done, None, **figures)

    def create(self, run: Run, **overrides: Any) -> Any:
        """The implementation of ``run`` with its options (``{capture}`` expanded) and ``overrides``."""
        given = run.all_options
        needs_capture = any(isinstance(v, str) and "{capture}" in v for v in given.values())
        options = expand(given, self.capture_dir() if needs_capture else None) | overrides
        return self.registry.get(self.role, run.implementation).create(options)

    def record(self, implementation: str, case: str, settings: dict[str, Any], seconds: float, peak_mb: float,
               errors: dict[str, float], error_key: str, reference: bool = False,
               detail: dict[str, Any] | None = None, label: str | None = None) -> dict[str, Any]:
        """A record of this role and preset; ``label`` names the point in plots and tables (default: the
        implementation and its options)."""
        r = make_record(self.role, implementation, self.preset, case, settings, seconds, peak_mb, errors,
                        error_key, self.versions, reference)
        options = settings.get("options") or {}
        r["label"] = label or implementation + ("[" + ",".join(f"{k}={v}" for k, v in sorted(options.items()))
                                                + "]" if options else "")
        if detail is not None:
            r["_detail"] = detail
        self.tick()
        return r

    def build(self, run: Run) -> Any:
        """The implementation of ``run``, or the exception its construction raised (reported per run)."""
        try:
            return self.create(run)
        except Exception as exc:  # noqa: BLE001  (a broken implementation must not stop the others)
            return exc

    def failed(self, implementation: str, case: str, settings: dict[str, Any], exc: BaseException,
               error_key: str) -> dict[str, Any]:
        """The record of a run that raised: no errors, ``failed`` holds the message (the traceback goes
        to the detail file)."""
        r = self.record(implementation, case, settings, float("nan"), float("nan"), {}, error_key,
                        detail={"traceback": traceback.format_exception(exc)})
        r["failed"] = f"{type(exc).__name__}: {exc}"
        return r
