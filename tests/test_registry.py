"""Registry: discovery through entry points of real (temporary) distributions, broken plugins, missing
dependencies, blocking, fallback lists, the pytest fixture."""

from __future__ import annotations

import json
import re

import pytest

from conftest import FAKE_DIST, install_distribution
from pgc.cli import main
from pgc.errors import PGCConfigError, PGCPluginError
from pgc.registry import ROLES, BLOCK_ENV, ImplementationSpec, Registry


def test_discovers_builtins_third_party_and_temporary_distribution(fake_distribution):
    reg = Registry.discover()
    ok = reg.get("filter", "tmp-ok")
    assert ok.available and ok.provider == FAKE_DIST and ok.plugin == "tmpok" and ok.reason is None
    box = reg.get("filter", "box")
    assert box.available and box.provider == "pgc-example-plugin"
    assert {i.provider for i in reg.list()} >= {"pgc", "pgc-example-plugin", FAKE_DIST}
    assert all(i.role in ROLES for i in reg.list())


def test_broken_plugin_is_reported_and_others_work(fake_distribution):
    reg = Registry.discover()
    broken = {b.plugin: b for b in reg.broken}
    assert broken["tmpbroken"].provider == FAKE_DIST
    assert broken["tmpbroken"].error == "ImportError: fakeplug_broken needs libfoo.so.3"
    assert "Traceback" in broken["tmpbroken"].traceback
    # the duplicate registration is refused and reported; the original stays
    assert "already provided by plugin 'tmpok'" in broken["tmpzdup"].error
    assert reg.get("filter", "tmp-ok").plugin == "tmpok"
    impl = reg.create("filter", "tmp-ok")
    assert impl.lowpass([[[1.0, 2.0, 3.0]]], [[1.0]], 3).tolist() == [[[1.0, 2.0, 3.0]]]


def test_missing_dependency_is_unavailable_with_install_hint(fake_distribution):
    reg = Registry.discover()
    impl = reg.get("filter", "tmp-missing")
    assert not impl.available and impl.missing == ("pgc_module_that_does_not_exist",)
    assert impl.reason == ("missing module(s) pgc_module_that_does_not_exist; install with: "
                           "pip install 'pgc[nonexistent]'")
    with pytest.raises(PGCPluginError, match="filter 'tmp-missing' is unavailable: missing module"):
        impl.create()


def test_factory_import_error_is_reported_on_create(fake_distribution):
    reg = Registry.discover()
    with pytest.raises(PGCPluginError, match=r"filter 'tmp-badfactory' \(plugin 'tmpok', distribution "
                                             r"tmp-pgc-plugins\): cannot import factory fakeplug_ok_impl_gone:X: "
                                             r"ModuleNotFoundError"):
        reg.create("filter", "tmp-badfactory")


def test_fallback_list_takes_the_first_available(fake_distribution):
    reg = Registry.discover()
    assert reg.first_available("filter", ["tmp-missing", "tmp-ok", "box"]).name == "tmp-ok"
    assert reg.first_available("filter", "box").name == "box"
    with pytest.raises(PGCPluginError, match=r"none of the filter implementations \['tmp-missing'\] is available:"
                                             r"\n  tmp-missing: missing module"):
        reg.first_available("filter", ["tmp-missing"])
    with pytest.raises(PGCConfigError, match=r"no filter named 'nope'; registered: .*box.*tmp-missing \(unavailable\)"):
        reg.first_available("filter", ["nope", "tmp-ok"])


def test_blocking_by_argument_and_env_var(fake_distribution, monkeypatch):
    reg = Registry.discover(block=["tmpbroken", "filter:tmp-ok"])
    assert "tmpbroken" not in {b.plugin for b in reg.broken}
    assert ("filter", "tmp-ok") not in reg.implementations
    assert ("filter", "tmp-missing") in reg.implementations
    monkeypatch.setenv(BLOCK_ENV, " example , tmpbroken")
    reg = Registry.discover()
    assert ("filter", "box") not in reg.implementations
    assert "tmpbroken" not in {b.plugin for b in reg.broken}
    assert ("filter", "tmp-ok") in reg.implementations


def test_unknown_role_is_a_broken_plugin(pgc_registry):
    class Plugin:
        @staticmethod
        def pgc_register_implementations():
            return [ImplementationSpec(role="shader", name="x", factory="m:X", description="")]

    from pgc.registry import hookimpl

    Plugin.pgc_register_implementations = hookimpl(Plugin.pgc_register_implementations)
    pgc_registry.add_plugin(Plugin, "weird")
    assert pgc_registry.list() == []
    assert "registers unknown role 'shader'" in pgc_registry.broken[0].error


def test_isolated_registry_fixture(pgc_registry):
    assert pgc_registry.list() == [] and pgc_registry.broken == []
    pgc_registry.add(ImplementationSpec(role="filter", name="box", factory="pgc_example_plugin.box_blur:BoxBlurFilter",
                                        description="", options="pgc_example_plugin.box_blur:BoxBlurOptions"))
    assert pgc_registry.create("filter", "box", {"passes": 2}).options.passes == 2


def test_pgc_plugins_json_lists_every_state(fake_distribution, capsys):
    assert main(["plugins", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert all({"role", "name", "provider", "available", "reason"} <= set(r) for r in rows)
    by_name = {r["name"]: r for r in rows}
    assert by_name["tmp-ok"] | {"description": None} == {
        "role": "filter", "name": "tmp-ok", "provider": FAKE_DIST, "plugin": "tmpok", "available": True,
        "reason": None, "description": None}
    assert by_name["tmp-missing"]["available"] is False
    assert "pip install 'pgc[nonexistent]'" in by_name["tmp-missing"]["reason"]
    assert by_name["tmpbroken"]["role"] is None and by_name["tmpbroken"]["available"] is False
    assert "fakeplug_broken needs libfoo.so.3" in by_name["tmpbroken"]["reason"]
    assert main(["plugins"]) == 0
    text = capsys.readouterr().out
    for role in ROLES:
        assert f"{role}:" in text
    assert "tmpbroken (tmp-pgc-plugins): plugin failed to load: ImportError" in text


BAD_PLUGIN = '''
from pgc.registry import ImplementationSpec, hookimpl
from pgc.roles.filter import Filter


class NotAFilter:
    """Has the method, but not the role's interface."""

    def lowpass(self, image, alpha, kernel_size):
        return image


class HalfFilter(Filter):
    """Subclasses the role and leaves its abstract method unimplemented."""


class Renamed(Filter):
    def lowpass(self, image, alpha, kernel_size):
        return image


def spec(name, factory, options=None):
    return ImplementationSpec(role="filter", name=name, factory=factory, description="", options=options)


@hookimpl
def pgc_register_implementations():
    return [spec("bad-class", "badplug:NotAFilter"), spec("bad-abstract", "badplug:HalfFilter"),
            spec("bad-import", "badplug_impl:Filter"), spec("bad-options", "badplug:Renamed", "badplug:NotAFilter")]
'''
BAD_REASONS = {
    "bad-class": "factory badplug:NotAFilter does not subclass the role's interface pgc.roles.filter:Filter",
    "bad-abstract": "factory badplug:HalfFilter leaves abstract method(s) lowpass of pgc.roles.filter:Filter "
                    "unimplemented",
    "bad-import": "cannot import factory badplug_impl:Filter: ImportError: badplug_impl needs libbaz.so.1",
    "bad-options": "options model badplug:NotAFilter is not a subclass of pgc.options.Options",
}


@pytest.fixture
def bad_plugins(tmp_path, monkeypatch):
    """An installed distribution ``bad-pgc-plugins`` (entry point ``badplug``) registering filters whose factories do
    not implement the role: not a subclass, an abstract method left, an import that fails, a bad options model."""
    import sys

    install_distribution(tmp_path / "site", monkeypatch, "bad-pgc-plugins",
                         {"badplug": BAD_PLUGIN, "badplug_impl": "raise ImportError('badplug_impl needs libbaz.so.1')\n"},
                         {"badplug": "badplug"})
    yield tmp_path
    for module in ("badplug", "badplug_impl"):
        sys.modules.pop(module, None)


def _label(name: str) -> str:
    return f"filter '{name}' (plugin 'badplug', distribution bad-pgc-plugins): "


def test_check_implementation_names_what_is_wrong(bad_plugins):
    from pgc.registry import check_implementation

    reg = Registry.discover()
    for name, reason in BAD_REASONS.items():
        impl = reg.get("filter", name)
        assert impl.available  # its dependencies are there: only importing the factory tells
        with pytest.raises(PGCPluginError) as exc:
            check_implementation(impl)
        assert str(exc.value) == _label(name) + reason
        assert impl.problem() == _label(name) + reason
        with pytest.raises(PGCPluginError, match="^" + re.escape(_label(name))):
            impl.create()
    assert check_implementation(reg.get("filter", "box")).__name__ == "BoxBlurFilter"
    assert reg.get("filter", "box").problem() is None


def test_pgc_plugins_lists_bad_plugins_as_unavailable_with_the_reason(bad_plugins, capsys):
    assert main(["plugins", "--role", "filter", "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    for name, reason in BAD_REASONS.items():
        assert rows[name]["available"] is False and rows[name]["reason"] == _label(name) + reason
        assert rows[name]["provider"] == "bad-pgc-plugins" and rows[name]["plugin"] == "badplug"
    assert rows["box"]["available"] is True and rows["box"]["reason"] is None
    assert main(["plugins", "--role", "filter"]) == 0
    text = capsys.readouterr().out
    assert "-- bad-abstract" in text and "unavailable: " + _label("bad-abstract") + BAD_REASONS["bad-abstract"] in text
    assert "ok box" in text


@pytest.mark.parametrize("name", list(BAD_REASONS))
def test_config_validate_refuses_a_chosen_bad_plugin_in_one_line(bad_plugins, capsys, name):
    cfg = bad_plugins / "bad.toml"
    cfg.write_text(f'[filter]\nuse = ["{name}", "box"]\n')
    assert main(["config", "validate", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pgc config: error: ") and err.count("\n") == 1
    assert _label(name) + BAD_REASONS[name] in err
    cfg.write_text('[filter]\nuse = "box"\n')  # registered but not chosen: no error
    assert main(["config", "validate", str(cfg)]) == 0


@pytest.mark.parametrize("argv", [["reconstruct", "{tmp}/no-capture", "--out", "{tmp}/asset"],
                                  ["demo", "--preset", "tiny", "--out", "{tmp}/demo"],
                                  ["synth", "{tmp}/capture", "--preset", "tiny"]],
                         ids=["reconstruct", "demo", "synth"])
def test_stage_commands_refuse_a_chosen_bad_plugin_before_any_work(bad_plugins, capsys, argv):
    cfg = bad_plugins / "bad.toml"
    cfg.write_text('[filter]\nuse = "bad-class"\n')
    argv = [a.format(tmp=bad_plugins) for a in argv] + ["--config", str(cfg)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"pgc {argv[0]}: error: ") and "\n" not in err
    assert _label("bad-class") + BAD_REASONS["bad-class"] in err
    assert not any((bad_plugins / d).exists() for d in ("asset", "demo", "capture"))  # nothing was written
