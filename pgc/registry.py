"""The plugin registry: discovers implementations through the entry-point group ``pgc``.

Every implementation (built-in or third-party) is declared by an :class:`ImplementationSpec` returned from
the ``pgc_register_implementations`` hook. Specs are cheap: the factory is a lazy ``"module:attr"``
reference and availability is decided by looking up module specs, never by importing them. Loading is
defensive: a plugin that fails to import or to register is listed with its error and the rest still work.

A plugin's import and registration run with SIGINT and SIGTERM deferred (:func:`plugin_code`): any exception
they raise, ``SystemExit`` and ``KeyboardInterrupt`` included, is the plugin's and marks it broken, while a real
Ctrl-C (or SIGTERM) that arrives meanwhile is delivered once the plugin's code has returned, so it still ends
the command (exit 130).

Blocking: entry-point names or ``role:name`` pairs listed in the environment variable ``PGC_BLOCK_PLUGINS``
(comma separated) or passed as ``block=`` are excluded.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata as metadata
import importlib.util
import inspect
import os
import signal
import threading
import traceback
from dataclasses import dataclass, field
from typing import Any, Iterable, Iterator

import pluggy

from pgc import hookspecs
from pgc.errors import PGCConfigError, PGCPluginError
from pgc.hookspecs import hookimpl  # re-exported for plugin authors

__all__ = ["ImplementationSpec", "Implementation", "Registry", "ROLES", "check_implementation", "hookimpl",
           "default_registry"]

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
    "body_model": "pgc.roles.body_model:BodyModel",
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


DEFERRED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def plugin_code() -> Iterator[None]:
    """Run a plugin's import or hook with SIGINT and SIGTERM deferred until it returns.

    While it runs, a KeyboardInterrupt can only come from the plugin itself (raised by its code, not by a
    signal), so callers treat it as the plugin's failure; a signal received meanwhile is raised again once the
    previous handlers are back, and ends the command as usual. Outside the main thread (where Python delivers no
    signals) nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, frame: received.append(signum)) for sig in DEFERRED_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        for sig in dict.fromkeys(received):
            signal.raise_signal(sig)


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
    _checked: type | PGCPluginError | None = field(default=None, init=False, repr=False, compare=False)

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

    @property
    def label(self) -> str:
        """``role 'name' (plugin 'P', distribution D)``: how messages name it."""
        return f"{self.role} '{self.name}' (plugin '{self.plugin}', distribution {self.provider})"

    @property
    def version(self) -> str | None:
        """The version of the distribution that provides it (None for one registered by hand)."""
        try:
            return metadata.version(self.provider)
        except (metadata.PackageNotFoundError, ValueError):
            return None

    def check(self) -> type:
        """The factory class, once checked to implement the role (:func:`check_implementation`; once per
        implementation, the outcome kept)."""
        if self._checked is None:
            try:
                self._checked = check_implementation(self)
            except PGCPluginError as exc:
                self._checked = exc
        if isinstance(self._checked, PGCPluginError):
            raise self._checked
        return self._checked

    def problem(self) -> str | None:
        """Why it cannot be used (its missing modules, or what :meth:`check` finds), or None; imports the
        factory of an available one."""
        if not self.available:
            return self.reason
        try:
            self.check()
        except PGCPluginError as exc:
            return str(exc)
        return None

    def options_model(self) -> type | None:
        """The options model (None for no options), imported and checked to subclass :class:`pgc.options.Options`
        (a light module: listing and validating configs import it, never the factory)."""
        from pgc.options import Options

        if self.spec.options is None:
            return None
        model = load_plugin_reference(self, "options model", self.spec.options)
        if not (isinstance(model, type) and issubclass(model, Options)):
            raise PGCPluginError(f"{self.label}: options model {self.spec.options} is not a subclass of "
                                 "pgc.options.Options")
        return model

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
            problems = []
            for err in exc.errors():
                loc = ".".join(str(p) for p in err["loc"])
                got = repr(err.get("input"))
                got = got if len(got) <= 60 else got[:57] + "..."
                problems.append(f"option '{loc}': {' '.join(str(err['msg']).split())} (got {got})")
            raise PGCConfigError(
                f"{where or self.role}: invalid options for {self.role} '{self.name}': " + "; ".join(problems)
                + f"; valid options: {', '.join(fields) or '(none)'}") from None

    def create(self, options: dict[str, Any] | Any | None = None) -> Any:
        """Build the implementation with validated options (a dict or an already validated model), after
        :meth:`check`."""
        cls = self.check()
        if options is None or isinstance(options, dict):
            options = self.validate_options(options)
        return cls(options) if options is not None else cls()


def load_plugin_reference(impl: Implementation, what: str, ref: str) -> Any:
    """``ref`` of ``impl``'s plugin imported as the plugin's code (:func:`plugin_code`); a failure raises
    :class:`PGCPluginError` naming the implementation and ``what`` could not be imported."""
    with plugin_code():
        try:
            return load_reference(ref)
        except BaseException as exc:  # anything raised while importing the plugin (sys.exit included) is its own
            raise PGCPluginError(f"{impl.label}: cannot import {what} {ref}: {type(exc).__name__}: {exc}") from exc


def check_implementation(impl: Implementation) -> type:
    """Import ``impl``'s factory and check that it implements its role: a class subclassing the role's interface
    (:data:`ROLES`) with no abstract method left, and an options model (when declared) subclassing
    :class:`pgc.options.Options`. Returns the class; anything else raises :class:`PGCPluginError` naming the
    role, the implementation, its plugin and distribution, and what is wrong. An unavailable implementation
    fails with its missing modules and their install hint."""
    if not impl.available:
        raise PGCPluginError(f"{impl.role} '{impl.name}' is unavailable: {impl.reason}")
    cls = load_plugin_reference(impl, "factory", impl.spec.factory)
    interface = load_reference(ROLES[impl.role])
    if not isinstance(cls, type):
        raise PGCPluginError(f"{impl.label}: factory {impl.spec.factory} is a {type(cls).__name__}, not a class "
                             f"subclassing {ROLES[impl.role]}")
    if not issubclass(cls, interface):
        raise PGCPluginError(f"{impl.label}: factory {impl.spec.factory} does not subclass the role's interface "
                             f"{ROLES[impl.role]}")
    if inspect.isabstract(cls):
        raise PGCPluginError(f"{impl.label}: factory {impl.spec.factory} leaves abstract method(s) "
                             f"{', '.join(sorted(cls.__abstractmethods__))} of {ROLES[impl.role]} unimplemented")
    impl.options_model()
    return cls


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
            with plugin_code():
                try:
                    module = ep.load()
                except BaseException as exc:  # a plugin's import (sys.exit or KeyboardInterrupt included) is its own
                    registry.broken.append(BrokenPlugin(ep.name, provider, f"{type(exc).__name__}: {exc}",
                                                        traceback.format_exc()))
                    continue
            registry.add_plugin(module, ep.name, provider)
        return registry

    def add_plugin(self, plugin: Any, name: str, provider: str | None = None) -> None:
        """Register a plugin object/module: its hooks are attached and its implementations collected."""
        provider = provider or name
        with plugin_code():
            try:
                self.plugin_manager.register(plugin, name=name)
                specs = getattr(plugin, "pgc_register_implementations", None)
                for spec in list(specs()) if specs is not None else []:
                    self.add(spec, provider=provider, plugin=name)
            except BaseException as exc:  # the plugin's hook, KeyboardInterrupt included (see plugin_code)
                if self.plugin_manager.is_registered(plugin):
                    self.plugin_manager.unregister(plugin)
                self.broken.append(BrokenPlugin(name, provider, f"{type(exc).__name__}: {exc}",
                                                traceback.format_exc()))

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
