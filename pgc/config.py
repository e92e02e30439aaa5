"""Run configuration: a TOML file -> a validated :class:`RunConfig`.

Format (every table optional; missing ones take the defaults of ``pgc/default_config.toml``)::

    [plugins]
    block = ["jax"]                 # entry-point names or "role:name" pairs to ignore

    [splat_renderer]                # one table per role
    use = ["torch", "jax"]          # one name, or an ordered fallback list: the first available wins
    [splat_renderer.torch]          # options of one implementation (validated by its schema)
    tile_size = 16

    [metric]
    use = ["psnr", "ssim"]          # the metric role uses every listed (available) metric

    [stages.fit_splats]             # options of a pipeline stage
    iterations = 3000

Everything is validated before any work starts: an unknown role, implementation, option or stage, or a
wrong type, fails with a message naming the file and key and listing what is valid.
"""

from __future__ import annotations

import copy
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pydantic

from pgc.errors import PGCConfigError, PGCDataError, PGCPluginError
from pgc.io.limits import read_toml
from pgc.options import Options
from pgc.registry import ROLES, Implementation, Registry

DEFAULT_CONFIG = Path(__file__).with_name("default_config.toml")
MULTI_ROLES = {"metric"}
"""Roles of which every listed implementation is used (not only the first available)."""


def deep_merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def load_toml(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    if path.is_dir():
        raise PGCConfigError(f"{path}: is a folder; give a config TOML file")
    if not path.is_file():
        raise PGCConfigError(f"{path}: config file not found")
    try:
        return read_toml(path)
    except PGCDataError as exc:  # a size or nesting limit
        raise PGCConfigError(str(exc)) from None
    except tomllib.TOMLDecodeError as exc:
        raise PGCConfigError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise PGCConfigError(f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason}); save the file as UTF-8 "
                             "TOML") from None
    except PermissionError as exc:
        raise PGCConfigError(f"{path}: cannot be read ({exc.strerror}); check its permissions") from None


@dataclass
class RoleChoice:
    """The implementation chosen for a role, with its validated options."""

    role: str
    requested: list[str]
    implementations: list[Implementation]
    """The chosen implementation(s): one, or for multi roles every available listed one."""
    options: dict[str, Options | None]
    """Validated options by implementation name (for every requested name that has options given)."""

    @property
    def implementation(self) -> Implementation:
        return self.implementations[0]

    @property
    def name(self) -> str:
        return self.implementation.name

    def create(self, name: str | None = None) -> Any:
        impl = self.implementation if name is None else next(i for i in self.implementations if i.name == name)
        return impl.create(self.options.get(impl.name) or impl.validate_options({}))

    def create_all(self) -> dict[str, Any]:
        return {impl.name: self.create(impl.name) for impl in self.implementations}


@dataclass
class RunConfig:
    roles: dict[str, RoleChoice]
    stages: dict[str, Options]
    block: list[str] = field(default_factory=list)
    source: str = "(defaults)"

    def create(self, role: str) -> Any:
        return self.roles[role].create()

    def stage(self, name: str) -> Any:
        return self.stages[name]

    def role_key(self, role: str, name: str | None = None) -> dict[str, Any]:
        """What of the configuration decides a role's results (its implementation, options and the version of
        the distribution providing it), for cache keys: of the implementation ``name`` among the role's chosen
        ones (a multi role such as ``metric`` has several), else of its first; name None when the role has
        nothing registered or ``name`` is not among its chosen implementations."""
        choice = self.roles.get(role)
        impl = None if choice is None else choice.implementation if name is None else next(
            (i for i in choice.implementations if i.name == name), None)
        if impl is None:
            return {"role": role, "name": None}
        opts = choice.options.get(impl.name)
        return {"role": role, "name": impl.name, "options": None if opts is None else opts.model_dump(mode="json"),
                "version": impl.version}

    def check_implementations(self) -> None:
        """Check every chosen available implementation before any work (:func:`pgc.registry.check_implementation`:
        importable, implementing its role); the bad ones raise one :class:`PGCPluginError` naming each. Imports
        the chosen factories (and so their libraries)."""
        problems = []
        for role, choice in self.roles.items():
            for impl in choice.implementations:
                if not impl.available:
                    continue
                try:
                    impl.check()
                except PGCPluginError as exc:
                    problems.append(f"[{role}] {exc}")
        if problems:
            raise PGCPluginError(f"{self.source}: " + "; ".join(problems) + "; fix or uninstall the plugin, block it "
                                 "([plugins] block), or choose another implementation in use")

    def to_dict(self) -> dict[str, Any]:
        """The resolved configuration with every default, in the TOML layout (and the choices made)."""
        out: dict[str, Any] = {"plugins": {"block": list(self.block)}}
        for role, choice in self.roles.items():
            table: dict[str, Any] = {"use": choice.requested if len(choice.requested) > 1 else choice.requested[0],
                                     "chosen": [i.name for i in choice.implementations]}
            for impl in choice.implementations:
                opts = choice.options.get(impl.name) or impl.validate_options({})
                if opts is not None:
                    table[impl.name] = opts.model_dump(mode="json")
            out[role] = table
        out["stages"] = {name: opts.model_dump(mode="json") for name, opts in self.stages.items()}
        return out


def resolve(data: dict[str, Any] | None = None, registry: Registry | None = None, source: str = "(defaults)",
            require_available: bool = True) -> RunConfig:
    """Validate ``data`` (a parsed TOML mapping, merged over the defaults) against the registry."""
    data = data or {}
    raw = deep_merge(load_toml(DEFAULT_CONFIG), data)
    block = raw.pop("plugins", {}).get("block", [])
    if not isinstance(block, list) or not all(isinstance(b, str) for b in block):
        raise PGCConfigError(f"{source}: [plugins] block must be a list of names")
    if registry is None:
        registry = Registry.discover(block=block)
    stages_raw = raw.pop("stages", {})
    roles: dict[str, RoleChoice] = {}
    for role, table in raw.items():
        where = f"{source}: [{role}]"
        if role not in ROLES:
            raise PGCConfigError(f"{source}: unknown table [{role}]; valid tables: plugins, stages, "
                                 f"{', '.join(ROLES)}")
        if not isinstance(table, dict):
            raise PGCConfigError(f"{where} must be a table with a 'use' key")
        table = dict(table)
        use = table.pop("use", None)
        names = [use] if isinstance(use, str) else use
        if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
            raise PGCConfigError(f"{where} use = {use!r}: give an implementation name or a list of names; "
                                 f"registered: {', '.join(i.name for i in registry.list(role)) or '(none)'}")
        user_role = role in data
        if not user_role:
            # A default choice must not break an installation that lacks its plugin: keep what is registered.
            names = [n for n in names if (role, n) in registry.implementations]
            if not names:
                continue
        try:
            impls = [registry.get(role, n) for n in names]  # unknown names fail here with the list
        except PGCConfigError as exc:
            raise PGCConfigError(f"{exc} (in {where} use); fix the name or install its plugin") from None
        options: dict[str, Options | None] = {}
        for key, value in table.items():
            if not isinstance(value, dict):
                raise PGCConfigError(f"{where} key '{key}': expected a table of options for one implementation "
                                     f"([{role}.{key}]); implementations: {', '.join(names)}")
            if key not in names:
                raise PGCConfigError(f"{where} has options for '{key}', which is not in use = {names}")
            options[key] = registry.get(role, key).validate_options(value, where=f"{source}: [{role}.{key}]")
        for impl in impls:  # validate defaults of the others too: a broken schema should fail early
            if impl.name not in options and impl.available:
                options[impl.name] = impl.validate_options({}, where=f"{source}: [{role}.{impl.name}]")
        if role in MULTI_ROLES:
            chosen = [i for i in impls if i.available]
            if not chosen and require_available and user_role:
                raise PGCPluginError(f"{where}: none of {names} is available")
        else:
            try:
                chosen = [registry.first_available(role, names)]
            except PGCPluginError:
                if require_available and user_role:
                    raise
                chosen = [impls[0]]
        roles[role] = RoleChoice(role, names, chosen or impls, options)
    return RunConfig(roles, resolve_stages(stages_raw, roles, source), block, source)


def resolve_stages(stages_raw: Any, roles: dict[str, RoleChoice], source: str) -> dict[str, Options]:
    """Validate the ``[stages]`` tables against the stage declarations (:mod:`pgc.stages`): every declared stage's
    settings (defaults where no table is given), then each stage's own rule (``Stage.check``)."""
    from pgc.stages import declared

    known = {name: stage for name, stage in declared().items() if stage.settings is not None}
    if not isinstance(stages_raw, dict):
        raise PGCConfigError(f"{source}: [stages] must be a table of stage tables")
    for name in stages_raw:
        if name not in known:
            raise PGCConfigError(f"{source}: unknown stage [stages.{name}]; stages: {', '.join(sorted(known))}")
    stages: dict[str, Options] = {}
    for name, stage in known.items():
        model = stage.settings
        given = stages_raw.get(name, {})
        try:
            settings = model.model_validate(given)
        except pydantic.ValidationError as exc:
            problems = "; ".join(f"option '{'.'.join(str(p) for p in e['loc'])}': {e['msg']} (got {e.get('input')!r})"
                                 for e in exc.errors())
            raise PGCConfigError(f"{source}: [stages.{name}] {problems}; valid options: "
                                 f"{', '.join(model.model_fields)}") from None
        if stage.check is not None:
            settings = stage.check(settings, given if isinstance(given, dict) else {}, roles, source)
        stages[name] = settings
    return stages


def load(path: str | Path | None = None, registry: Registry | None = None,
         require_available: bool = True) -> RunConfig:
    """Load and validate a config file (None: the defaults)."""
    if path is None:
        return resolve(None, registry, require_available=require_available)
    return resolve(load_toml(path), registry, source=str(path), require_available=require_available)


def dumps_toml(data: dict[str, Any]) -> str:
    """Serialise a resolved config mapping as TOML (tables of scalars and lists)."""

    def fmt(value: Any) -> str:
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, (int, float)):
            return repr(value)
        if isinstance(value, str):
            return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
        if isinstance(value, (list, tuple)):
            return "[" + ", ".join(fmt(v) for v in value) + "]"
        if value is None:
            return '"none"'
        raise TypeError(f"cannot write {type(value).__name__} to TOML")

    lines: list[str] = []

    def table(prefix: str, mapping: dict[str, Any]) -> None:
        scalars = {k: v for k, v in mapping.items() if not isinstance(v, dict)}
        tables = {k: v for k, v in mapping.items() if isinstance(v, dict)}
        if prefix and (scalars or not tables):
            lines.append(f"\n[{prefix}]")
        for k, v in scalars.items():
            if v is None:  # TOML has no null: an omitted key takes its default
                continue
            lines.append(f"{k} = {fmt(v)}")
        for k, v in tables.items():
            table(f"{prefix}.{k}" if prefix else k, v)

    table("", data)
    return "\n".join(lines).lstrip("\n") + "\n"
