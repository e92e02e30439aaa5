"""The stage declarations (pgc.stages): complete and consistent, what the configuration and every command run,
and what the docs' stage tables show; the runner's cache keys follow the declarations (a changed setting, role
or version recomputes that stage and what reads its changed output, nothing else)."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import numpy as np
import pytest

from pgc import config
from pgc.errors import PGCConfigError
from pgc.options import Options, count
from pgc.stages import declared, settings_models, stage_table
from pgc.stages.declaration import COMMANDS, SOURCES, Stage

ROOT = Path(__file__).resolve().parents[1]
ARCHITECTURE_COLUMNS = ("stage", "config table", "folder", "settings", "progress events")


def test_every_stage_is_declared_once_with_a_version_a_command_and_outputs():
    stages = declared()
    assert list(stages) == ["mesh", "garment", "fit_splats", "base_color", "material", "body_fit", "animate", "render",
                            "eval"]
    for name, stage in stages.items():
        assert stage.name == name and isinstance(stage, Stage)
        assert isinstance(stage.version, str) and stage.version.strip(), name
        assert stage.command in COMMANDS and stage.outputs and stage.folder, name
        assert stage.settings is not None or stage.role is not None, f"{name}: configured by nothing"


def test_inputs_name_earlier_stages_of_the_same_command_or_sources():
    stages = declared()
    order = list(stages)
    for name, stage in stages.items():
        for inp in stage.inputs:
            if inp in SOURCES:
                continue
            assert inp in stages, f"{name} reads '{inp}': neither a stage nor a source"
            assert order.index(inp) < order.index(name), f"{name} reads '{inp}', which runs after it"
            if stage.cached:  # its key reads the upstream output's hash from the same stage cache
                assert stages[inp].command == stage.command, f"{name} reads '{inp}' of another command"


def test_settings_resolve_and_the_config_knows_exactly_the_declared_stages():
    from pgc.registry import ROLES

    models = settings_models()
    for name, stage in declared().items():
        if stage.settings is not None:
            assert issubclass(stage.settings, Options) and isinstance(stage.settings(), stage.settings)
        for role in (stage.role, *stage.key_roles(stage.settings() if stage.settings else None),
                     *stage.fingerprint_roles):
            assert role is None or role in ROLES, f"{name}: unknown role {role}"
    cfg = config.load(require_available=False)
    assert list(cfg.stages) == list(models)
    assert {n: type(s) for n, s in cfg.stages.items()} == models
    with pytest.raises(PGCConfigError, match=r"unknown stage \[stages.mesh\]; stages: animate, base_color"):
        config.resolve({"stages": {"mesh": {}}}, require_available=False)


def test_the_render_stage_owns_its_kernel_rule():
    from pgc.stages.render import check_kernel_metric

    assert declared()["render"].check is check_kernel_metric
    cfg = config.resolve({"metric": {"use": ["psnr"]}}, require_available=False)
    assert cfg.stage("render").kernel.mode == "error"  # the default falls back without its metric
    with pytest.raises(PGCConfigError, match=r"\[stages.render.kernel\] metric = 'lpips' is not among"):
        config.resolve({"metric": {"use": ["psnr"]}, "stages": {"render": {"kernel": {"mode": "metric"}}}},
                       require_available=False)


def test_the_render_key_holds_the_kernel_rule_metric_not_the_run_metric_list(tmp_path):
    """The kernel rule scores with one metric: its options enter the render's key; the run's other metrics,
    their number and order do not (adding a metric re-evaluates a run without rendering it again)."""
    from pgc.events import Reporter
    from pgc.pipeline.cache import StageCache
    from pgc.pipeline.runner import StageContext, StageRunner

    render = declared()["render"]

    def key(data):
        cfg = config.resolve(data, require_available=False)
        runner = StageRunner(StageCache(tmp_path), StageContext(cfg, Reporter.silent(), None),
                             {"run": "r", "asset": "a", "light": "l"})
        return runner.key(render)

    base = key({"metric": {"use": ["psnr", "lpips"]}})
    assert key({"metric": {"use": ["fsim", "ssim", "lpips", "psnr-exposure", "psnr"]}}) == base
    assert key({"metric": {"use": ["psnr", "lpips"], "lpips": {"net": "vgg"}}}) != base
    error_rule = {"stages": {"render": {"kernel": {"mode": "error"}}}}
    assert key({"metric": {"use": ["psnr", "lpips"]}, **error_rule}) == key({"metric": {"use": ["ssim"]},
                                                                            **error_rule}) != base
    assert render.key_roles(config.resolve({}, require_available=False).stage("render"))["metric"] == "lpips"


def test_every_command_runs_exactly_its_declared_stages_in_order():
    from pgc.pipeline import animate, evaluate, reconstruct, render

    bound = {"reconstruct": reconstruct.STAGES, "animate": animate.STAGES, "render": render.STAGES,
             "eval": evaluate.STAGES}
    for command, pairs in bound.items():
        assert [s.name for s, _ in pairs] == [s.name for s in declared().values() if s.command == command]
        for stage, step in pairs:
            assert stage is declared()[stage.name]
            assert (step.load is not None) == stage.cached, stage.name


def test_the_docs_stage_tables_match_the_declarations():
    pipeline = (ROOT / "docs" / "pipeline.md").read_text(encoding="utf-8")
    assert "\n".join(stage_table()) in pipeline, "docs/pipeline.md: regenerate with pgc.stages.stage_table()"
    architecture = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert "\n".join(stage_table(ARCHITECTURE_COLUMNS)) in architecture, (
        f"docs/architecture.md: regenerate with pgc.stages.stage_table({ARCHITECTURE_COLUMNS})")


LAB_NOTE = re.compile(r"\d+(\.\d+)? ?dB|LPIPS \d|\d against \d|on (the|two) \w+ scenes?|seeds? \d")


def test_stage_settings_describe_options_without_measured_figures():
    """The settings declared with the stages (the two fits' live with their role contracts, in pgc.roles)."""
    for name, model in settings_models().items():
        if not model.__module__.startswith("pgc.stages."):
            continue
        text = inspect.getsource(model)
        assert not LAB_NOTE.search(text), f"[stages.{name}]: measured figures belong in docs/: {LAB_NOTE.search(text)}"


# ------------------------------------------------------------------------------------------- the runner


class Scale(Options):
    factor: int = count(2, 1, 100)


class Offset(Options):
    add: int = count(0, 0, 100)


TOY = (Stage("a", "reconstruct", "1", ("capture",), ("a.npy",), "T/a", roles=("filter",)),
       Stage("b", "reconstruct", "1", ("a",), ("b.npy",), "T/b", settings=Scale),
       Stage("c", "reconstruct", "1", ("b",), ("c.npy",), "T/c", settings=Offset))


def _toy_steps(log: list[str]):
    from pgc.pipeline.runner import Step

    def compute(name, fn):
        def run(ctx, folder):
            log.append(name)
            value = fn(ctx)
            np.save(folder / f"{name}.npy", value)
            return value, {"sum": float(value.sum())}
        return run

    def load(name):
        return lambda ctx, folder: np.load(folder / f"{name}.npy")

    return {"a": Step(compute("a", lambda ctx: np.arange(3) + ctx.inputs), load("a")),
            "b": Step(compute("b", lambda ctx: ctx.values["a"] * ctx.cfg.stage("b").factor), load("b")),
            "c": Step(compute("c", lambda ctx: ctx.values["b"] + ctx.cfg.stage("c").add), load("c"))}


@pytest.fixture(scope="module")
def registry():
    from pgc.registry import Registry

    return Registry.discover()


def _run(tmp_path, registry, filt="box", factor=2, add=0, capture=0, stages=TOY):
    from pgc.events import Reporter
    from pgc.pipeline.cache import StageCache
    from pgc.pipeline.runner import StageContext, StageRunner

    base = config.resolve({"filter": {"use": filt}}, registry, require_available=False)
    cfg = config.RunConfig(base.roles, {"b": Scale(factor=factor), "c": Offset(add=add)})
    log: list[str] = []
    steps = _toy_steps(log)
    runner = StageRunner(StageCache(tmp_path), StageContext(cfg, Reporter.silent(), capture), {"capture": capture})
    for stage in stages:
        runner.run(stage, steps[stage.name])
    return log, runner


def test_a_changed_setting_recomputes_that_stage_and_those_reading_its_changed_output(tmp_path, registry):
    assert _run(tmp_path, registry)[0] == ["a", "b", "c"]
    log, runner = _run(tmp_path, registry)
    assert log == [] and runner.seconds == {"a": 0.0, "b": 0.0, "c": 0.0}
    assert _run(tmp_path, registry, add=5)[0] == ["c"]  # downstream only
    assert _run(tmp_path, registry, add=5, factor=3)[0] == ["b", "c"]
    log, runner = _run(tmp_path, registry, add=5, factor=3)
    assert log == [] and runner.ctx.values["c"].tolist() == [5, 8, 11]
    assert runner.figures()[0] == {"a": {"sum": 3.0}, "b": {"sum": 9.0}, "c": {"sum": 24.0}}


def test_a_changed_role_source_or_version_recomputes_that_stage(tmp_path, registry):
    from dataclasses import replace

    _run(tmp_path, registry)
    # another filter: 'a' is recomputed; its output is the same bytes, so 'b' and 'c' are reused
    assert _run(tmp_path, registry, filt="opencv")[0] == ["a"]
    assert _run(tmp_path, registry, filt="opencv", capture=1)[0] == ["a", "b", "c"]
    newer = (TOY[0], replace(TOY[1], version="2"), TOY[2])
    assert _run(tmp_path, registry, filt="opencv", capture=1, stages=newer)[0] == ["b"]


def test_a_stage_that_does_not_write_its_declared_outputs_fails(tmp_path, registry):
    from dataclasses import replace

    wrong = (replace(TOY[0], outputs=("a.npy", "missing.json")),)
    with pytest.raises(RuntimeError, match=r"stage 'a' did not write its declared outputs \['missing.json'\]"):
        _run(tmp_path, registry, stages=wrong)
    assert not (tmp_path / "a").exists()


def test_a_stage_reading_something_the_runner_lacks_fails_before_computing(tmp_path, registry):
    with pytest.raises(KeyError, match="stage 'b' reads 'a', which is neither a source"):
        _run(tmp_path, registry, stages=TOY[1:])
