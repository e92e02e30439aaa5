"""pgc sweep: the file's validation, the task engine (in-process and on a 2-process LocalCluster: retries after a
killed worker, pinned threads), sharing of upstream work, resume, and in-process = cluster records."""

from __future__ import annotations

import json
import math
import os
import signal
import sys
import threading
import time
from pathlib import Path

import pytest

from conftest import fast_sweep_config
from pgc.errors import PGCConfigError
from pgc.sweep.engine import Task, run_tasks, thread_environment

GOOD = """
[sweep]
steps = ["reconstruct", "animate"]
motions = ["goalpost"]
[scenes.a]
preset = "tiny"
[configurations.base]
[table]
rows = ["configuration"]
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sw.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("old, new, message", [
    ('preset = "tiny"', 'preset = "tiny"\ncolour = "red"', "[scenes.a].colour: unknown key"),
    ('preset = "tiny"', 'fabric = "silk"', "[scenes.a].fabric: unknown fabric 'silk'"),
    ('[configurations.base]', '[configurations.base]\nbrdf = { use = "phong" }', "[configurations.base]"),
    ('[configurations.base]', '[configurations.base.stages.render]\nfoo = 1', "option 'foo'"),
    ('[configurations.base]', '[configurations.base.stages.nostage]', "unknown stage [stages.nostage]"),
    ('"animate"]', '"simulate"]', "[sweep].steps: unknown step 'simulate'"),
    ('steps = ["reconstruct", "animate"]', 'steps = ["animate"]', "each step needs the ones before it"),
    ('motions = ["goalpost"]', 'motions = ["moonwalk"]', "'moonwalk' is neither a built-in motion"),
    ('motions = ["goalpost"]', 'motions = ["cmu:99_99"]', "no shipped clip 99_99.amc"),
    ('motions = ["goalpost"]', 'motions = ["walk.bvh"]', "'walk.bvh' is neither a built-in motion"),
    ('rows = ["configuration"]', 'rows = ["colour"]', "[table].rows: unknown field 'colour'"),
    ('[table]', '[tables]', "tables: unknown key"),
    ('rows = ["configuration"]', 'reference = { variant = "hybrid", light = "capture" }', "[table].reference: give one"),
    ('rows = ["configuration"]', 'reference = "hybrid"', "[table].reference: give one field and its reference"),
    ('rows = ["configuration"]', 'reference = { seed = 0 }', "[table].reference.seed: give a field the records pair"),
    ('rows = ["configuration"]', 'reference = { colour = "red" }', "[table].reference.colour: give a field"),
    ('rows = ["configuration"]', 'reference = { variant = ["hybrid"] }', "[table].reference.variant: give one value"),
    ('preset = "tiny"', 'preset = "knit"\ndetail = "lace"', "[scenes.a].detail: unknown detail 'lace'; choose from none"),
    ('preset = "tiny"', 'fit = ["resting", "tight"]', "[scenes.a].fit: unknown fit 'tight'; choose from loose"),
    ('preset = "tiny"', 'looseness = 0.5', "[scenes.a].looseness: 0.5: give the garment's clearance"),
    ('preset = "tiny"', 'looseness = "wide"', "[scenes.a].looseness: 'wide': give"),
    ('preset = "tiny"', 'looseness = true', "[scenes.a].looseness: True: give"),
    ('preset = "tiny"', 'capture_light = "sunset"', "[scenes.a].capture_light: unknown capture_light 'sunset'; "
                                                    "choose from uniform, sky-sun"),
])
def test_bad_sweep_file_fails_before_any_work_naming_file_and_key(tmp_path, old, new, message):
    from pgc.sweep.runner import run_sweep

    assert old in GOOD
    path = _write(tmp_path, GOOD.replace(old, new))
    with pytest.raises(PGCConfigError) as exc:
        run_sweep(path, tmp_path / "out")
    assert str(path) in str(exc.value) and message in str(exc.value)
    assert not (tmp_path / "out").exists()


def test_sweep_cli_reports_a_bad_file_as_one_error_line(tmp_path, capsys):
    from pgc.cli import main

    path = _write(tmp_path, GOOD.replace('preset = "tiny"', 'seed = -1'))
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "[scenes.a].seed" in err and str(path) in err


def test_sweeps_take_shipped_and_file_clips(tmp_path):
    import shutil

    from pgc.motion.drive import shipped_clip
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.work import plan

    shutil.copy(shipped_clip("cmu:02_03.bvh"), tmp_path / "run.bvh")
    path = _write(tmp_path, GOOD.replace('motions = ["goalpost"]', 'motions = ["cmu:02_01", "run.bvh"]'))
    sweep = load_sweep(path)
    assert sweep.motions == ["cmu:02_01", "run.bvh"]
    tasks, units, _ = plan(sweep, tmp_path / "out")
    run_keys = {u.run_task for u in units}
    runs = sorted(Path(t.args[3]).name for t in tasks if t.key in run_keys)
    assert [r.rsplit("-", 1)[0] for r in runs] == ["a-cmu-02_01", "a-run"]  # no ':' in a folder name


def test_a_result_counts_only_with_its_folder(tmp_path):
    """A rerun skips a task whose result is on record only while the folder it wrote exists: a scene renamed
    between runs keeps its task keys but not its folders, and must not send later tasks to missing folders."""
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.work import plan, result_path

    sweep = load_sweep(_write(tmp_path, GOOD.replace('steps = ["reconstruct", "animate"]',
                                                     'steps = ["reconstruct", "animate", "render"]\nholdout_every = 2')))
    out = tmp_path / "out"
    tasks, _, done = plan(sweep, out)
    assert [t.key.split("-")[0] for t in tasks] == ["capture", "split", "asset", "run"] and not done
    for t in tasks:
        result_path(out, t.key).parent.mkdir(parents=True, exist_ok=True)
        result_path(out, t.key).write_text("{}")
    again, _, done = plan(sweep, out)
    assert [t.key for t in again] == [t.key for t in tasks] and not done  # results without folders: all run again
    folders = {"capture": [tasks[0].args[1]], "split": list(tasks[1].args[1:3]), "asset": [tasks[2].args[1]],
               "run": [tasks[3].args[3]]}
    for paths in folders.values():
        for folder in paths:
            Path(folder).mkdir(parents=True)
    resumed, _, done = plan(sweep, out)
    assert not resumed and set(done) == {t.key for t in tasks}
    Path(folders["run"][0]).rmdir()
    resumed, _, _ = plan(sweep, out)
    assert [t.key for t in resumed] == [tasks[3].key]
    assert plan(sweep, out, need_folders=False)[0] == []  # --collect tabulates the results alone


def test_a_renamed_scene_seeds_its_new_folders_from_the_folders_on_record(tmp_path):
    """A scene renamed in the sweep file keeps its task keys: its asset and run tasks run again into folders of
    the new name, each seeded from the folder its finished task recorded, so no stage is computed again."""
    import json

    from pgc.sweep.spec import load_sweep
    from pgc.sweep.work import plan, recorded_folder, result_path

    out = tmp_path / "out"
    tasks, _, _ = plan(load_sweep(_write(tmp_path, GOOD)), out)
    capture, asset, run = tasks
    recorded = {asset.key: {"asset": asset.args[1]}, run.key: {"run": run.args[3], "configuration": "base"}}
    for t in tasks:
        Path(t.args[1] if t is not run else t.args[3]).mkdir(parents=True)
        result_path(out, t.key).parent.mkdir(parents=True, exist_ok=True)
        result_path(out, t.key).write_text(json.dumps(recorded.get(t.key, {})))
    renamed, _, done = plan(load_sweep(_write(tmp_path, GOOD.replace("[scenes.a]", "[scenes.b]"))), out)
    assert [t.key for t in renamed] == [capture.key, asset.key, run.key] and not done
    new_asset, new_run = renamed[1], renamed[2]
    assert "/b-" in new_asset.args[1] and new_asset.args[4] == asset.args[1]  # seeded from the old asset
    assert "/b-" in new_run.args[3] and new_run.args[8] == run.args[3]  # and from the old run
    assert new_run.deps == (new_asset.key,)
    Path(new_run.args[3]).mkdir(parents=True)  # a resumed task keeps its own folder: no donor then
    assert recorded_folder(out, run.key, "run", Path(new_run.args[3])) is None
    assert recorded_folder(out, run.key, "run", Path(run.args[3])) is None  # its own folder


def test_scene_lists_expand_into_named_scenes(tmp_path):
    from pgc.sweep.spec import load_sweep

    path = _write(tmp_path, GOOD.replace('preset = "tiny"', 'preset = "tiny"\nseed = [0, 3]\nfabric = ["knit", "fleece"]'))
    names = [s.name for s in load_sweep(path).scenes]
    assert names == ["a-seed0-knit", "a-seed0-fleece", "a-seed3-knit", "a-seed3-fleece"]


def test_knit_scene_keys_expand_and_leave_other_scenes_unchanged(tmp_path):
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.work import scene_key

    text = GOOD + '[scenes.k]\npreset = "knit"\ndetail = ["relief", "seams"]\nfit = "resting"\nlooseness = [0.012, 0.03]\n'
    sweep = load_sweep(_write(tmp_path, text))
    scenes, cfg = sweep.scenes, sweep.configurations[0].cfg
    assert [s.name for s in scenes] == ["a", "k-relief-looseness0.012", "k-relief-looseness0.03",
                                        "k-seams-looseness0.012", "k-seams-looseness0.03"]
    plain = {"preset": "tiny", "garment": None, "fabric": None, "seed": 0, "framing": None}
    assert scenes[0].synth == plain  # no new keys: a sweep without them keeps its scene keys and captures
    assert scenes[2].synth == plain | {"preset": "knit", "detail": "relief", "fit": "resting", "looseness": 0.03}
    assert len({scene_key(s, cfg) for s in scenes}) == 5


def test_make_capture_passes_the_scene_spec_as_pgc_synth_does(tmp_path, monkeypatch):
    import pgc.synth.generate as generate_mod
    from pgc.sweep.work import make_capture
    from pgc.synth.generate import get_preset

    calls = []

    def generate(folder, preset, **kw):
        Path(folder).mkdir(parents=True, exist_ok=True)
        calls.append((preset, kw))

    monkeypatch.setattr(generate_mod, "generate", generate)
    spec = {"preset": "knit", "garment": None, "fabric": "fleece", "seed": 2, "framing": "body", "detail": "seams",
            "fit": "loose", "looseness": 0.03}
    make_capture(spec, str(tmp_path / "captures" / "k-abc"), {}, "(test)", str(tmp_path))
    make_capture(spec | {"framing": None, "detail": None}, str(tmp_path / "captures" / "k-def"), {}, "(test)",
                 str(tmp_path))
    assert all(kw.pop("renderer").role == "scene_renderer" for _, kw in calls)  # the configuration's
    assert all(kw.pop("body_model").role == "body_model" for _, kw in calls)
    # `pgc synth OUT --preset knit --fabric fleece --seed 2 --framing body --detail seams --fit loose --looseness 0.03`
    assert calls[0] == (get_preset("knit", framing="body"), {"garment": None, "fabric": "fleece", "seed": 2,
                                                            "looseness": 0.03, "detail": "seams", "fit": "loose"})
    assert calls[1][0] == get_preset("knit") and calls[1][0].framing == "garment" and calls[1][1]["detail"] is None
    assert "capture_light" not in calls[1][1]  # not given: the preset's, and the capture cache's key as before
    assert (tmp_path / "results" / "capture-abc.json").is_file()
    make_capture(spec | {"capture_light": "sky-sun"}, str(tmp_path / "captures" / "k-sun"), {}, "(test)",
                 str(tmp_path))  # `pgc synth ... --capture-light sky-sun`
    assert calls[2][1]["capture_light"] == "sky-sun"


def test_capture_light_names_scenes_and_records(tmp_path):
    from pgc.sweep.runner import records_of
    from pgc.sweep.spec import load_sweep
    from pgc.sweep.work import plan

    sweep = load_sweep(_write(tmp_path, GOOD.replace('preset = "tiny"',
                                                     'preset = "tiny"\ncapture_light = ["uniform", "sky-sun"]')))
    assert [s.name for s in sweep.scenes] == ["a-uniform", "a-sky-sun"]
    assert [s.synth["capture_light"] for s in sweep.scenes] == ["uniform", "sky-sun"]
    plain = load_sweep(_write(tmp_path, GOOD)).scenes[0]
    assert "capture_light" not in plain.synth  # a scene without it keeps its key (and its cached capture)
    tasks, units, _ = plan(sweep, tmp_path / "out")
    assert len({t.key for t in tasks if t.key.startswith("capture-")}) == 2
    records = records_of(sweep, units, {}, {t.key: "not run" for t in tasks})
    assert {r["capture_light"] for r in records} == {"uniform", "sky-sun"}


def _add(a: int, b: int, *deps: int) -> int:
    return a + b + sum(deps)


def _fail() -> int:
    raise RuntimeError("broken on purpose")


def test_engine_in_process_orders_dependencies_and_contains_failures():
    tasks = [Task("c", _add, (1, 0), ("a", "b")), Task("a", _add, (1, 2)), Task("b", _add, (10, 0), ("a",)),
             Task("x", _fail), Task("y", _add, (0, 0), ("x",))]
    out = run_tasks(tasks)
    assert out.results == {"a": 3, "b": 13, "c": 17}
    assert out.failed == {"x": "RuntimeError: broken on purpose", "y": "needs failed task x"}


def _log(order: list, key: str, *deps: object) -> str:
    order.append(key)
    return key


def test_engine_in_process_runs_higher_priorities_first_after_their_dependencies():
    order: list[str] = []
    tasks = [Task("late", _log, (order, "late"), (), -1), Task("a", _log, (order, "a")),
             Task("late-after-b", _log, (order, "late-after-b"), ("b",), -1), Task("b", _log, (order, "b"), ("late",))]
    run_tasks(tasks)
    assert order == ["a", "late", "b", "late-after-b"]  # 'b' needs 'late': priority never breaks a dependency


def _worker_threads(*deps: object) -> dict:
    import torch

    return {"omp": os.environ.get("OMP_NUM_THREADS"), "xla": os.environ.get("XLA_FLAGS"),
            "torch": torch.get_num_threads(), "pid": os.getpid()}


def _slow_marked(folder: str, *deps: object) -> int:
    """Appends this attempt's pid to a file, then works for 6 s: a worker killed meanwhile loses the task."""
    with open(Path(folder) / "attempts", "a") as f:
        f.write(f"{os.getpid()}\n")
    time.sleep(6)
    return os.getpid()


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of 2 worker processes (1 task each, threads pinned to cores // 2)."""
    import cloudpickle
    from distributed import LocalCluster

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    cores = len(os.sched_getaffinity(0))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      env=thread_environment(max(1, cores // 2))) as c:
        yield c


@pytest.mark.slow
def test_engine_on_two_worker_processes_pins_threads_and_matches_in_process(cluster):
    tasks = [Task("a", _add, (1, 2)), Task("b", _add, (10, 0), ("a",)), Task("t1", _worker_threads, (), ("a",)),
             Task("t2", _worker_threads, (), ("b",)), Task("x", _fail), Task("y", _add, (0, 0), ("x",))]
    out = run_tasks(tasks, cluster.scheduler_address, retries=1)
    here = run_tasks([t for t in tasks if not t.key.startswith("t")])
    assert {k: out.results[k] for k in here.results} == here.results
    assert out.failed == here.failed
    n = max(1, len(os.sched_getaffinity(0)) // 2)
    for key in ("t1", "t2"):
        info = out.results[key]
        assert info["pid"] != os.getpid() and info["omp"] == str(n) and info["torch"] == n
        assert f"intra_op_parallelism_threads={n}" in info["xla"] and "--xla_cpu_multi_thread_eigen=false" in info["xla"]


def _kill_worker_when_running(folder: Path, killed: list[int]) -> None:
    """Wait until the marked task has started, then SIGKILL the worker process running it."""
    deadline = time.time() + 60
    while time.time() < deadline and not killed:
        if (folder / "attempts").is_file():
            pid = int((folder / "attempts").read_text().split()[0])
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)
        time.sleep(0.2)


@pytest.mark.slow
def test_a_killed_worker_loses_only_its_task_which_is_retried(cluster, tmp_path):
    killed: list[int] = []
    watcher = threading.Thread(target=_kill_worker_when_running, args=(tmp_path, killed))
    watcher.start()
    tasks = [Task("slow", _slow_marked, (str(tmp_path),)), Task("after", _add, (1, 1), ("slow",)),
             Task("other", _add, (5, 5))]
    out = run_tasks(tasks, cluster.scheduler_address, retries=2)
    watcher.join()
    attempts = [int(p) for p in (tmp_path / "attempts").read_text().split()]
    assert killed and attempts[0] == killed[0] and len(attempts) == 2  # killed once, run once more
    assert out.failed == {}
    assert out.results["slow"] == attempts[1] != killed[0]
    assert out.results["after"] == 2 + attempts[1] and out.results["other"] == 10


def _logged(folder: str, key: str, *deps: object) -> str:
    """Appends ``key`` to the folder's log when it starts, then works for 0.3 s."""
    with open(Path(folder) / "started", "a") as f:
        f.write(f"{key}\n")
    time.sleep(0.3)
    return key


@pytest.mark.slow
def test_the_cluster_runs_ready_tasks_by_priority(cluster, tmp_path):
    # 'first' frees four low-priority tasks while ten high-priority tasks without dependencies still wait: a
    # scheduler that queues the dependency-free tasks would start the freed ones ahead of them
    low = [Task(f"low-{i}", _logged, (str(tmp_path), f"low-{i}"), ("first",), -1) for i in range(4)]
    high = [Task(f"high-{i}", _logged, (str(tmp_path), f"high-{i}")) for i in range(10)]
    first = Task("first", _logged, (str(tmp_path), "first"))
    out = run_tasks([*low, first, *high], cluster.scheduler_address)
    assert out.failed == {} and len(out.results) == 15
    started = (tmp_path / "started").read_text().split()
    assert sorted(started[:11]) == sorted(["first"] + [t.key for t in high])


TINY = """
[sweep]
name = "t"
base = "tiny"
config = "{fast}"
steps = ["reconstruct", "animate", "render", "eval"]
motions = ["goalpost"]
lights = ["capture", "low-key"]
[scenes.s]
preset = "tiny"
[configurations.four-views]
[configurations.one-view]
stages.render = {{ views = 1 }}
[table]
rows = ["configuration"]
columns = ["variant"]
metrics = ["psnr"]
"""


def _comparable(records: list[dict], out: Path) -> list[dict]:
    """Records without timings and with paths relative to their sweep folder."""
    keep = []
    for r in records:
        r = {k: v for k, v in r.items() if k != "seconds"}
        for k in ("asset", "run", "capture"):
            if r.get(k):
                r[k] = str(Path(r[k]).relative_to(out))
        keep.append(r)
    return keep


@pytest.fixture(scope="module")
def tiny_sweep(tmp_path_factory):
    from pgc.sweep.runner import run_sweep

    root = tmp_path_factory.mktemp("sweep")
    path = root / "tiny.toml"
    path.write_text(TINY.format(fast=fast_sweep_config(root)))
    # this process's own thread counts (torch: every core), not a worker's allotment: the records must not
    # depend on them
    return path, root / "here", run_sweep(path, root / "here")


@pytest.mark.slow
def test_tiny_sweep_shares_the_asset_and_the_simulation(tiny_sweep):
    path, out, result = tiny_sweep
    assert result["failed"] == {} and result["computed"] == 4  # capture, one asset, two runs
    records = result["records"]
    assert len(records) == 12 and {r["variant"] for r in records} == {"hybrid", "3dgs_only", "pbr_only"}
    assert {r["light"] for r in records} == {"capture", "low-key"}
    for r in records:  # the low key light's frames and truth live in the run's relit run
        folder = Path(r["run"]) / ("relit/low-key" if r["light"] == "low-key" else "")
        assert json.loads((folder / "metrics.json").read_text())["light"]["kind"] == (
            "envmap" if r["light"] == "low-key" else "capture")
    assert len({r["asset"] for r in records}) == 1 and len({r["run"] for r in records}) == 2
    one = next(r for r in records if r["configuration"] == "one-view")
    run = json.loads((out / "results" / f"run-{Path(one['run']).name.rsplit('-', 1)[1]}.json").read_text())
    assert run["seeded"]  # its caches came from the other configuration's run
    sims = [{p.parent.name: json.loads(p.read_text())["key"] for p in (Path(r["run"]) / "stages").glob("*/stage.json")}
            for r in records]
    assert sims[0] and all(s == sims[0] for s in sims)  # the same simulation (stage keys) in both runs
    for r in records:
        assert all(v == v for v in r["metrics"].values()) and "psnr" in r["metrics"]
    html = (out / "sweep.html").read_text()
    assert "four-views" in html and "plots/speed-error.png" in html
    assert (out / "plots" / "metric-psnr.png").stat().st_size > 5000
    assert len((out / "sweep.csv").read_text().splitlines()) == 13


@pytest.mark.slow
def test_rerun_recomputes_nothing(tiny_sweep):
    from pgc.sweep.runner import run_sweep

    path, out, first = tiny_sweep
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("stage.json")}
    again = run_sweep(path, out)
    assert again["computed"] == 0 and again["failed"] == {}
    assert again["records"] == first["records"]
    assert {p: p.stat().st_mtime_ns for p in out.rglob("stage.json")} == stamps


@pytest.mark.slow
def test_cluster_sweep_with_a_killed_worker_gives_the_in_process_records(tiny_sweep, cluster):
    from pgc.sweep.runner import run_sweep

    path, here, reference = tiny_sweep
    out = here.parent / "cluster"
    killed: list[int] = []

    def kill_during_a_run() -> None:
        deadline = time.time() + 600
        while time.time() < deadline and not killed:
            locks = list((out / "runs").glob("*/.pgc.lock")) if (out / "runs").is_dir() else []
            for lock in locks:
                try:
                    pid = json.loads(lock.read_text())["pid"]
                except (ValueError, KeyError):
                    continue
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                break
            time.sleep(0.5)

    watcher = threading.Thread(target=kill_during_a_run)
    watcher.start()
    result = run_sweep(path, out, scheduler=cluster.scheduler_address)
    watcher.join()
    assert killed, "no run task was seen running"
    assert result["failed"] == {}
    got, want = _comparable(result["records"], out), _comparable(reference["records"], here)
    # the same records, values included (exactly): other processes, other thread counts (1 per worker here,
    # every core in-process), a retried task
    assert got == want
    assert all(math.isfinite(v) for r in got for v in r["metrics"].values())


@pytest.mark.slow
def test_a_renamed_scene_computes_no_stage_again(tiny_sweep):
    """Renaming the scene in the file reruns its capture (from the capture cache), asset and run tasks into new
    folders, each seeded from the folder on record: every stage is reused and the metrics are the same. (Into a
    copy of the sweep's results, so that the shared sweep's records stay as they were.)"""
    import shutil

    from pgc.sweep.runner import run_sweep

    path, out, first = tiny_sweep
    renamed = path.with_name("tiny-renamed.toml")
    renamed.write_text(path.read_text().replace("[scenes.s]", "[scenes.s-renamed]"))
    copy = out.with_name("renamed")
    shutil.copytree(out / "results", copy / "results")
    again = run_sweep(renamed, copy)
    assert again["failed"] == {} and again["computed"] == 4  # capture, asset, two runs
    old = {(r["configuration"], r["light"], r["variant"]): r for r in first["records"]}
    for r in again["records"]:
        before = old[(r["configuration"], r["light"], r["variant"])]
        assert r["metrics"] == before["metrics"]
        for field, caches in (("asset", ("stages/mesh/stage.json", "stages/fit_splats/stage.json")),
                              ("run", ("stages/animate/stage.json", "render/stage.json"))):
            new_folder, old_folder = Path(r[field]), Path(before[field])
            assert new_folder.name.startswith("s-renamed-") and copy in new_folder.parents
            for cache in caches:
                assert (new_folder / cache).stat().st_mtime_ns == (old_folder / cache).stat().st_mtime_ns


@pytest.mark.slow
def test_a_changed_metric_evaluates_again_without_simulating_again(tiny_sweep):
    """A downstream change (here one more metric, FSIM) gives every run a new key; each new run folder starts from the
    earlier folder of its asset and motion, so the simulation, the render (the filter's kernel is chosen by
    LPIPS alone, not by the list of metrics) and the ground truth's frames are reused."""
    from pgc.sweep.runner import run_sweep

    path, out, first = tiny_sweep
    changed = path.with_name("tiny-more-metrics.toml")
    changed.write_text(path.read_text().replace("[configurations.four-views]", "[configurations.four-views]\n"
                                                'metric = { use = ["psnr", "psnr-exposure", "ssim", "fsim", "lpips"] }')
                       .replace("stages.render = { views = 1 }", "stages.render = { views = 1 }\n"
                                'metric = { use = ["psnr", "psnr-exposure", "ssim", "fsim", "lpips"] }'))
    again = run_sweep(changed, out)
    assert again["failed"] == {} and again["computed"] == 2  # the two runs; capture and asset are shared
    old_runs = {r["configuration"]: Path(r["run"]) for r in first["records"]}
    for r in again["records"]:
        new = Path(r["run"])
        assert new != old_runs[r["configuration"]] and "fsim" in r["metrics"]
        result = json.loads((out / "results" / f"run-{new.name.rsplit('-', 1)[1]}.json").read_text())
        assert result["seeded"]
        old = old_runs[r["configuration"]]
        truth = sorted(p.relative_to(old) for p in (old / "gt").rglob("*.npz"))
        assert truth and all((new / p).is_file() for p in truth)
        for cache in ("stages/animate/stage.json", "render/stage.json", *truth):  # came with the earlier folder
            assert (new / cache).stat().st_mtime_ns == (old / cache).stat().st_mtime_ns
    same = {(r["configuration"], r["light"], r["variant"]): r["metrics"]["psnr"] for r in first["records"]}
    assert all(r["metrics"]["psnr"] == same[(r["configuration"], r["light"], r["variant"])] for r in again["records"])
