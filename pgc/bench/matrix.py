"""The bench matrix: per role, which implementations run with which option variants, and each preset's
workload parameters. A TOML file, one table per role::

    [filter]
    implementations = "*"                  # every installed implementation, or a list of names
    variants = { opencv = [{}, { method = "box3" }] }   # option tables per implementation: one run each
    tiny = { size = 96, kernels = [7, 31] }             # workload parameters of each preset
    default = { size = 512, kernels = [7, 31, 71] }

A preset table may hold ``options``: options given to every implementation of the role in that preset
(under each variant's own options), e.g. ``tiny = { options = { target_vertices = 3000 } }``.

Roles missing from the file are not run. Unknown roles, unknown or unavailable implementations, factories that
do not implement their role and invalid options fail before any work starts, naming the file and listing what
exists (``"*"`` leaves out, with the reason, the ones that cannot run). Option strings may contain
``{capture}``: the synthetic capture's folder.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pgc.errors import PGCConfigError, PGCDataError
from pgc.io.limits import read_toml

DEFAULT_MATRIX = Path(__file__).with_name("default_matrix.toml")
PRESETS = ("tiny", "default")
ROLE_KEYS = {"implementations", "variants", *PRESETS}
WORKLOADS: dict[str, str] = {
    "reconstructor": "pgc.bench.workloads.reconstructor",
    "splat_renderer": "pgc.bench.workloads.splat",
    "brdf": "pgc.bench.workloads.brdf",
    "pbr_renderer": "pgc.bench.workloads.pbr",
    "albedo_estimator": "pgc.bench.workloads.albedo",
    "simulator": "pgc.bench.workloads.simulator",
    "filter": "pgc.bench.workloads.filter",
    "metric": "pgc.bench.workloads.metric",
    "scene_renderer": "pgc.bench.workloads.scene_renderer",
    "calibrator": "pgc.bench.workloads.calibrator",
    "body_model": "pgc.bench.workloads.body_model",
}
"""Role -> module of its workload (imported only when the role runs); the matrix validates roles against it."""


@dataclass
class Run:
    """One implementation with one option variant (options as written, before ``{capture}`` expansion)."""

    implementation: str
    options: dict[str, Any] = field(default_factory=dict)
    """The variant's own options (what names the run)."""
    common: dict[str, Any] = field(default_factory=dict)
    """The preset's options for every implementation of the role (the variant's own win)."""

    @property
    def all_options(self) -> dict[str, Any]:
        return self.common | self.options


@dataclass
class RolePlan:
    role: str
    runs: list[Run]
    workload: dict[str, Any]
    skipped: dict[str, str] = field(default_factory=dict)
    """Implementations left out of a ``"*"`` selection because they cannot run
    (:meth:`pgc.registry.Implementation.problem`): name -> reason."""


def load_matrix(path: str | os.PathLike | None, registry: Any, preset: str,
                roles: list[str] | None = None) -> list[RolePlan]:
    """The validated plan of ``path`` (default: the shipped matrix) for ``preset``, limited to ``roles``."""
    path = Path(path) if path is not None else DEFAULT_MATRIX
    if preset not in PRESETS:
        raise PGCConfigError(f"unknown bench preset '{preset}'; presets: {', '.join(PRESETS)}")
    try:
        table = read_toml(path)
    except FileNotFoundError:
        raise PGCConfigError(f"bench matrix {path} does not exist") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise PGCConfigError(f"bench matrix {path}: invalid TOML ({exc})") from None
    except PGCDataError as exc:  # a size or nesting limit
        raise PGCConfigError(f"bench matrix {exc}") from None
    for role in list(table) + list(roles or []):
        if role not in WORKLOADS:
            raise PGCConfigError(f"{path}: unknown role '{role}'; roles with a bench workload: "
                                 f"{', '.join(WORKLOADS)}")
    missing = [r for r in roles or [] if r not in table]
    if missing:
        raise PGCConfigError(f"{path}: no table for role(s) {', '.join(missing)}; the matrix has: "
                             f"{', '.join(table) or '(none)'}")
    plans = []
    for role, spec in table.items():
        if roles and role not in roles:
            continue
        plans.append(_role_plan(path, role, spec, registry, preset))
    return plans


def _role_plan(path: Path, role: str, spec: dict[str, Any], registry: Any, preset: str) -> RolePlan:
    where = f"{path} [{role}]"
    extra = set(spec) - ROLE_KEYS
    if extra:
        raise PGCConfigError(f"{where}: unknown keys {sorted(extra)}; allowed: {', '.join(sorted(ROLE_KEYS))}")
    names = spec.get("implementations", "*")
    skipped: dict[str, str] = {}
    if names == "*":
        impls = registry.list(role)
        reasons = {i.name: i.problem() for i in impls}
        skipped = {name: reason for name, reason in reasons.items() if reason}
        names = [name for name, reason in reasons.items() if not reason]
    elif not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise PGCConfigError(f"{where}: 'implementations' must be \"*\" or a list of names, got {names!r}")
    for name in names:
        try:
            impl = registry.get(role, name)
        except PGCConfigError as exc:  # the registry's message lists the registered implementations
            raise PGCConfigError(f"{where}: {exc}") from None
        if not impl.available:
            raise PGCConfigError(f"{where}: {role} '{name}' is unavailable: {impl.reason}")
        impl.check()
    variants = spec.get("variants", {})
    for name in variants:
        if name not in names:
            raise PGCConfigError(f"{where}: variants for '{name}', which is not in the matrix; "
                                 f"implementations: {', '.join(names)}")
    workload = spec.get(preset, {})
    if not isinstance(workload, dict) or not isinstance(workload.get("options", {}), dict):
        raise PGCConfigError(f"{where}: '{preset}' must be a table of workload parameters ('options' a table)")
    common = workload.get("options", {})
    runs = []
    for name in names:
        options_list = variants.get(name, [{}])
        if not isinstance(options_list, list) or not all(isinstance(o, dict) for o in options_list):
            raise PGCConfigError(f"{where}: variants.{name} must be a list of option tables")
        for options in options_list:
            registry.get(role, name).validate_options(common | options, where=f"{where} variants.{name}")
            runs.append(Run(name, dict(options), dict(common)))
    return RolePlan(role, runs, workload, skipped)


def expand(options: dict[str, Any], capture: str | None) -> dict[str, Any]:
    """``options`` with ``{capture}`` in string values replaced by the capture folder."""
    if capture is None:
        return dict(options)
    return {k: v.replace("{capture}", capture) if isinstance(v, str) else v for k, v in options.items()}
