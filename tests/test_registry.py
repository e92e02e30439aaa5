"""Registry: discovery through entry points of real (temporary) distributions, broken plugins, missing
dependencies, blocking, fallback lists, the pytest fixture."""

from __future__ import annotations

import json

import pytest

from conftest import FAKE_DIST
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
    with pytest.raises(PGCPluginError, match=r"filter 'tmp-badfactory': cannot import fakeplug_ok_impl_gone:X: "
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
