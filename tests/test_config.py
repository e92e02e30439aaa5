"""Run configuration: selection, fallbacks, blocking, and errors that name the key and list what is valid."""

from __future__ import annotations

import json
import subprocess
import tomllib

import pytest

from pgc import config
from pgc.cli import main
from pgc.errors import PGCConfigError, PGCPluginError
from pgc.registry import Registry


@pytest.fixture
def registry(fake_distribution) -> Registry:
    """Only the example plugin and the temporary distribution: other roles' defaults are skipped."""
    import importlib

    reg = Registry()
    reg.add_plugin(importlib.import_module("pgc_example_plugin.register"), "example", "pgc-example-plugin")
    reg.add_plugin(importlib.import_module("fakeplug_ok"), "tmpok", "tmp-pgc-plugins")
    reg.add_plugin(importlib.import_module("fakeplug_missing"), "tmpmissing", "tmp-pgc-plugins")
    return reg


def _load(tmp_path, text: str, registry: Registry, **kw) -> config.RunConfig:
    path = tmp_path / "run.toml"
    path.write_text(text)
    return config.load(path, registry=registry, **kw)


def test_selects_implementation_with_options(tmp_path, registry):
    cfg = _load(tmp_path, '[filter]\nuse = "box"\n[filter.box]\npasses = 2\n', registry)
    assert cfg.roles["filter"].name == "box"
    assert cfg.create("filter").options.passes == 2
    assert set(cfg.roles) == {"filter"}  # defaults of roles with nothing registered are left out
    assert cfg.to_dict()["filter"] == {"use": "box", "chosen": ["box"], "box": {"passes": 2}}


def test_fallback_list(tmp_path, registry):
    cfg = _load(tmp_path, '[filter]\nuse = ["tmp-missing", "box", "tmp-ok"]\n', registry)
    assert cfg.roles["filter"].name == "box"
    with pytest.raises(PGCPluginError, match=r"none of the filter implementations \['tmp-missing'\] is available"):
        _load(tmp_path, '[filter]\nuse = ["tmp-missing"]\n', registry)
    # without require_available (pgc config show) the choice is shown even when nothing is installed
    cfg = _load(tmp_path, '[filter]\nuse = ["tmp-missing"]\n', registry, require_available=False)
    assert cfg.roles["filter"].name == "tmp-missing"


def test_unknown_implementation_lists_registered(tmp_path, registry):
    with pytest.raises(PGCConfigError, match=r"no filter named 'gaussian'; registered: box, tmp-badfactory, "
                                             r"tmp-missing \(unavailable\), tmp-ok"):
        _load(tmp_path, '[filter]\nuse = "gaussian"\n', registry)


def test_unknown_option_names_key_and_valid_options(tmp_path, registry):
    with pytest.raises(PGCConfigError) as err:
        _load(tmp_path, '[filter]\nuse = "box"\n[filter.box]\nradius = 3\n', registry)
    msg = str(err.value)
    assert "run.toml: [filter.box]: invalid options for filter 'box'" in msg
    assert "option 'radius': Extra inputs are not permitted (got 3)" in msg
    assert "valid options: passes" in msg


def test_wrong_type_names_key(tmp_path, registry):
    with pytest.raises(PGCConfigError, match=r"option 'passes': Input should be a valid integer.*\(got 'three'\)"):
        _load(tmp_path, '[filter]\nuse = "box"\n[filter.box]\npasses = "three"\n', registry)


def test_structural_errors(tmp_path, registry):
    with pytest.raises(PGCConfigError, match=r"unknown table \[filtr\]; valid tables: plugins, stages, "
                                             r"reconstructor, splat_renderer"):
        _load(tmp_path, '[filtr]\nuse = "box"\n', registry)
    with pytest.raises(PGCConfigError, match=r"\[filter\] has options for 'tmp-ok', which is not in use = \['box'\]"):
        _load(tmp_path, '[filter]\nuse = "box"\n[filter.tmp-ok]\nx = 1\n', registry)
    with pytest.raises(PGCConfigError, match=r"\[filter\] use = 3: give an implementation name or a list"):
        _load(tmp_path, '[filter]\nuse = 3\n', registry)
    with pytest.raises(PGCConfigError, match=r"unknown stage \[stages\.nope\]; stages: "):
        _load(tmp_path, '[stages.nope]\nx = 1\n', registry)
    with pytest.raises(PGCConfigError, match=r"not valid TOML"):
        _load(tmp_path, '[filter\n', registry)
    with pytest.raises(PGCConfigError, match=r"missing\.toml: config file not found"):
        config.load(tmp_path / "missing.toml", registry=registry)
    with pytest.raises(PGCConfigError, match=r"\[plugins\] block must be a list of names"):
        _load(tmp_path, '[plugins]\nblock = "example"\n', registry)


def test_blocking_by_config(tmp_path, fake_distribution):
    """[plugins] block applies to the discovery that resolve() does itself."""
    path = tmp_path / "run.toml"
    path.write_text('[plugins]\nblock = ["example"]\n[filter]\nuse = "tmp-ok"\n')
    cfg = config.load(path)
    assert cfg.roles["filter"].name == "tmp-ok" and cfg.block == ["example"]
    path.write_text('[plugins]\nblock = ["example"]\n[filter]\nuse = "box"\n')
    with pytest.raises(PGCConfigError, match="no filter named 'box'"):
        config.load(path)


def _cli(capsys, *args: str) -> subprocess.CompletedProcess:
    """Run ``pgc ARGS`` in this process; returns code, stdout and stderr like subprocess.run."""
    code = main(list(args))
    captured = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, captured.out, captured.err)


def test_config_show_and_validate_cli(tmp_path, capsys):
    out = _cli(capsys, "config", "show")
    assert out.returncode == 0, out.stderr
    shown = tomllib.loads(out.stdout)  # the printed config is valid TOML
    assert shown["plugins"] == {"block": []} and "stages" in shown
    resolved = config.load(require_available=False).to_dict()
    assert set(shown) == set(resolved)
    assert json.loads(_cli(capsys, "config", "show", "--json").stdout)["plugins"] == {"block": []}
    good = tmp_path / "good.toml"
    good.write_text('[filter]\nuse = "box"\n')
    out = _cli(capsys, "config", "validate", str(good))
    assert out.returncode == 0 and out.stdout.startswith(f"{good}: ok (") and "filter=box" in out.stdout
    bad = tmp_path / "bad.toml"
    bad.write_text('[filter]\nuse = "gaussian"\n')
    out = _cli(capsys, "config", "validate", str(bad))
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.startswith("pgc config: error: no filter named 'gaussian'; registered: ")
