"""The plugin registry: discovers implementations through the entry-point group ``pgc``.

Every implementation (built-in or third-party) is declared by an :class:`ImplementationSpec` returned from
the ``pgc_register_implementations`` hook. Specs are cheap: the factory is a lazy ``"module:attr"``
reference and availability is decided by looking up module specs, never by importing them. Loading is
defensive: a plugin that fails to import or to register is listed with its error and the rest still work.

Blocking: entry-point names or ``role:name`` pairs listed in the environment variable ``PGC_BLOCK_PLUGINS``
(comma separated) or passed as ``block=`` are excluded.
"""

from __future__ import annotations

import importlib
import importlib.metadata as metadata
import importlib.util
import os
import traceback
from dataclasses import dataclass, field
from typing import Any, Iterable

import pluggy

from pgc import hookspecs
from pgc.errors import PGCConfigError, PGCPluginError
from pgc.hookspecs import hookimpl  # re-exported for plugin authors

__all__ = ["ImplementationSpec", "Implementation", "Registry", "ROLES", "hookimpl", "default_registry"]

ENTRY_POINT_GROUP = "pgc"
BLOCK_ENV = "PGC_BLOCK_PLUGINS"

ROLES: dict[str, str] = {
    "reconstructor": "pgc.roles.reconstructor:Reconstructor",
    "splat_renderer": "pgc.roles.splat_renderer:SplatRenderer",
    "brdf": "pgc.roles.brdf:BRDF",
    "pbr_renderer": "pgc.roles.pbr_renderer:PBRRenderer",
    "albedo_estimator": "pgc.roles.albedo_estimator:AlbedoEstimator",
    "simulator": "pgc.roles.simulator:Simulator",
    "filter": "pgc.roles.filter:Filter",
    "metric": "pgc.roles.metric:Metric",
    "scene_renderer": "pgc.roles.scene_renderer:SceneRenderer",
    "calibrator": "pgc.roles.calibrator:Calibrator",
}
"""Role name -> its abstract interface (lazy reference)."""


def load_reference(ref: str) -> Any:
    """Import ``"package.module:attr"`` and return the attribute."""
    module_name, _, attr = ref.partition(":")
    if not attr:
        raise PGCPluginError(f"reference '{ref}' must have the form 'module:attr'")
    obj = importlib.import_module(module_name)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def module_available(name: str) -> bool:
    """Whether ``name`` can be imported, decided without importing it (only its parent packages)."""
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


@dataclass(frozen=True)
class ImplementationSpec:
    """What a plugin declares about one implementation of a role. Cheap to build: no heavy imports."""

    role: str
    name: str
    factory: str
    """``"module:attr"`` of the class implementing the role; called with a validated options object."""
    description: str
    options: str | None = None
    """``"module:attr"`` of its pydantic options model (in a light module), or None for no options."""
    requires: tuple[str, ...] = ()
    """Importable module names it needs (checked with find_spec, never imported to check)."""
    extra: str | None = None
    """The pip extra that installs what it needs, e.g. ``"torch"`` for ``pip install 'pgc[torch]'``."""


@dataclass
class Implementation:
    """A registered implementation with its availability, as the registry reports it."""

    spec: ImplementationSpec
    provider: str
    """The distribution that provides it (or the plugin name when unknown)."""
    plugin: str
    """The entry-point name that registered it."""
    missing: tuple[str, ...] = ()

    @property
    def role(self) -> str:
        return self.spec.role

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def available(self) -> bool:
        return not self.missing

    @property
    def reason(self) -> str | None:
        if not self.missing:
            return None
        hint = f"pip install 'pgc[{self.spec.extra}]'" if self.spec.extra else f"pip install {' '.join(self.missing)}"
        return f"missing module(s) {', '.join(self.missing)}; install with: {hint}"

    def options_model(self) -> type | None:
        return None if self.spec.options is None else load_reference(self.spec.options)

    def validate_options(self, options: dict[str, Any] | None, where: str = "") -> Any:
        """Validate ``options`` against the options model; unknown keys and wrong types fail clearly."""
        model = self.options_model()
        options = dict(options or {})
        if model is None:
            if options:
                raise PGCConfigError(f"{where or self.role + '.' + self.name}: implementation '{self.name}' takes "
                                     f"no options, got {sorted(options)}")
            return None
        import pydantic

        try:
            return model.model_validate(options)
        except pydantic.ValidationError as exc:
            fields = sorted(model.model_fields)
            lines = []
            for err in exc.errors():
                loc = ".".join(str(p) for p in err["loc"])
                lines.append(f"  option '{loc}': {err['msg']} (got {err.get('input')!r})")
            raise PGCConfigError(
                f"{where or self.role}: invalid options for {self.role} '{self.name}':\n" + "\n".join(lines)
                + f"\n  valid options: {', '.join(fields) or '(none)'}") from None

    def create(self, options: dict[str, Any] | Any | None = None) -> Any:
        """Build the implementation with validated options (a dict or an already validated model)."""
        if not self.available:
            raise PGCPluginError(f"{self.role} '{self.name}' is unavailable: {self.reason}")
        if options is None or isinstance(options, dict):
            options = self.validate_options(options)
        try:
            cls = load_reference(self.spec.factory)
        except (Exception, SystemExit) as exc:  # an import error (or sys.exit) inside the plugin: report it
            raise PGCPluginError(f"{self.role} '{self.name}': cannot import {self.spec.factory}: "
                                 f"{type(exc).__name__}: {exc}") from exc
        return cls(options) if options is not None else cls()


@dataclass
class BrokenPlugin:
    """An entry point that could not be loaded or registered."""

    plugin: str
    provider: str
    error: str
    traceback: str = ""


@dataclass
class Registry:
    """Implementations by (role, name), discovered from entry points or registered by hand."""

    implementations: dict[tuple[str, str], Implementation] = field(default_factory=dict)
    broken: list[BrokenPlugin] = field(default_factory=list)
    blocked: set[str] = field(default_factory=set)
    plugin_manager: pluggy.PluginManager = field(default_factory=lambda: _new_plugin_manager())

    @classmethod
    def discover(cls, block: Iterable[str] = (), group: str = ENTRY_POINT_GROUP) -> "Registry":
        """Load every entry point of ``group`` defensively and collect their implementations."""
        env_block = {b.strip() for b in os.environ.get(BLOCK_ENV, "").split(",") if b.strip()}
        registry = cls(blocked=set(block) | env_block)
        for ep in sorted(metadata.entry_points(group=group), key=lambda e: e.name):
            provider = ep.dist.name if ep.dist is not None else ep.name
            if ep.name in registry.blocked:
                continue
            try:
                module = ep.load()
            except (Exception, SystemExit) as exc:  # a plugin calling sys.exit on import must not end the caller
                registry.broken.append(BrokenPlugin(ep.name, provider, f"{type(exc).__name__}: {exc}",
                                                    traceback.format_exc()))
                continue
            registry.add_plugin(module, ep.name, provider)
        return registry

    def add_plugin(self, plugin: Any, name: str, provider: str | None = None) -> None:
        """Register a plugin object/module: its hooks are attached and its implementations collected."""
        provider = provider or name
        try:
            self.plugin_manager.register(plugin, name=name)
            specs = getattr(plugin, "pgc_register_implementations", None)
            specs = list(specs()) if specs is not None else []
            for spec in specs:
                self.add(spec, provider=provider, plugin=name)
        except (Exception, SystemExit) as exc:
            if self.plugin_manager.is_registered(plugin):
                self.plugin_manager.unregister(plugin)
            self.broken.append(BrokenPlugin(name, provider, f"{type(exc).__name__}: {exc}", traceback.format_exc()))

    def add(self, spec: ImplementationSpec, provider: str = "local", plugin: str = "local") -> None:
        """Add one implementation. A duplicate (role, name) or an unknown role is an error."""
        if spec.role not in ROLES:
            raise PGCPluginError(f"plugin '{plugin}' registers unknown role '{spec.role}'; roles: {', '.join(ROLES)}")
        if f"{spec.role}:{spec.name}" in self.blocked:
            return
        key = (spec.role, spec.name)
        if key in self.implementations:
            other = self.implementations[key]
            raise PGCPluginError(f"plugin '{plugin}' registers {spec.role} '{spec.name}', already provided by "
                                 f"plugin '{other.plugin}' ({other.provider})")
        missing = tuple(m for m in spec.requires if not module_available(m))
        self.implementations[key] = Implementation(spec, provider, plugin, missing)

    @property
    def hook(self) -> Any:
        """The pluggy hook relay for emitting events (``registry.hook.pgc_stage_started(...)``)."""
        return self.plugin_manager.hook

    def list(self, role: str | None = None) -> list[Implementation]:
        return [impl for (r, _), impl in sorted(self.implementations.items()) if role is None or r == role]

    def get(self, role: str, name: str) -> Implementation:
        """The implementation ``name`` of ``role``; an unknown one fails listing what there is."""
        if role not in ROLES:
            raise PGCConfigError(f"unknown role '{role}'; roles: {', '.join(ROLES)}")
        impl = self.implementations.get((role, name))
        if impl is None:
            names = [i.name + ("" if i.available else " (unavailable)") for i in self.list(role)]
            raise PGCConfigError(f"no {role} named '{name}'; registered: {', '.join(names) or '(none)'}")
        return impl

    def first_available(self, role: str, names: str | Iterable[str]) -> Implementation:
        """The first available of ``names`` (an ordered fallback list), like Mitsuba's set_variant(a, b)."""
        names = [names] if isinstance(names, str) else list(names)
        reasons = []
        for name in names:
            impl = self.get(role, name)
            if impl.available:
                return impl
            reasons.append(f"{name}: {impl.reason}")
        raise PGCPluginError(f"none of the {role} implementations {names} is available:\n  " + "\n  ".join(reasons))

    def create(self, role: str, name: str | Iterable[str], options: dict[str, Any] | None = None) -> Any:
        """Build the first available implementation among ``name`` with ``options``."""
        return self.first_available(role, name).create(options)


def _new_plugin_manager() -> pluggy.PluginManager:
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    return pm


_DEFAULT: Registry | None = None


def default_registry(refresh: bool = False) -> Registry:
    """The process-wide registry discovered from installed entry points (cached)."""
    global _DEFAULT
    if _DEFAULT is None or refresh:
        _DEFAULT = Registry.discover()
    return _DEFAULT


def collect_specs(package: str) -> list[ImplementationSpec]:
    """Gather ``SPECS`` from every ``specs_*.py`` module of ``package`` (each a light module).

    A backend package keeps one such module per area (e.g. ``specs_splat.py``, ``specs_xpbd.py``), so that
    areas are declared independently and registering never imports the backend's array library.
    """
    import pkgutil

    pkg = importlib.import_module(package)
    specs: list[ImplementationSpec] = []
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda i: i.name):
        if info.name.startswith("specs_"):
            specs.extend(importlib.import_module(f"{package}.{info.name}").SPECS)
    return specs


def spec_plugin_hook(package: str):
    """Build the registration hook of a package whose specs live in ``specs_*.py`` modules."""

    @hookimpl
    def pgc_register_implementations() -> list[ImplementationSpec]:
        return collect_specs(package)

    return pgc_register_implementations
