"""Shared fixtures: small, seeded data built in memory (no files outside tmp_path)."""

from __future__ import annotations

import fcntl
import os
import resource
from pathlib import Path

import pgc  # noqa: F401  (before numpy: it holds numpy's BLAS to one thread, see pgc.cores)
import numpy as np
import pytest

from pgc.types import Camera, Capture, Light, Mesh, View, WorldGaussians


def tilted_camera(w: int = 32, h: int = 24, f: float = 40.0, skew: float = 0.0) -> Camera:
    """A small pinhole camera tilted 0.1 rad about x, off-centre principal point, optional skew (px).

    The splat tests size their backgrounds and cotangents for the default 32 x 24 px."""
    R = np.array([[1.0, 0, 0], [0, np.cos(0.1), -np.sin(0.1)], [0, np.sin(0.1), np.cos(0.1)]])
    return Camera(K=[[f, skew, w / 2 + 0.3], [0, f * 1.05, h / 2 - 0.2], [0, 0, 1]], R=R, t=[0.02, -0.01, 0.1],
                  width=w, height=h)


def overlapping_gaussians(n: int, seed: int, sh_k: int = 16) -> WorldGaussians:
    """``n`` random Gaussians in front of :func:`tilted_camera` (depth complexity in the tens), SH with
    ``sh_k`` coefficients per channel."""
    rng = np.random.default_rng(seed)
    means = np.c_[rng.uniform(-0.35, 0.35, n), rng.uniform(-0.25, 0.25, n), rng.uniform(0.8, 1.6, n)]
    return WorldGaussians(means=means, quats=rng.normal(size=(n, 4)), scales=rng.uniform(0.01, 0.12, (n, 3)),
                          opacities=rng.uniform(0.05, 1.0, n), sh=rng.normal(0, 0.4, (n, sh_k, 3)))


os.environ.setdefault("PGC_CAPTURE_CACHE", "off")  # no test fills the user's capture cache (tests of it set their own)
os.environ.setdefault("OMP_WAIT_POLICY", "passive")
"""OpenMP threads (the native XPBD kernel's, torch's, Open3D's; here and in the tests' subprocesses) sleep at a
barrier instead of spinning: under ``make test`` two workers share the cores, and a thread spinning for one that
is descheduled burns CPU for nothing (the native simulator's tests: 64 -> 48 CPU s on 2 cores; results do not
depend on it). Set before any OpenMP runtime loads (none of the imports above loads one)."""


def pytest_configure(config: pytest.Config) -> None:
    """Under pytest-xdist (``make test`` runs ``-n 2``), each worker's torch gets its share of the cores, so two
    workers never run more torch threads than there are cores; with ``--dist loadfile`` the files are handed out in
    the order of :func:`pytest_collection_modifyitems` (pytest-xdist's default reorders them by their number of
    tests, most first: the few-test, costliest files, test_kill's 2 tests or test_isa_levels' 3, came last and one
    worker ran on alone)."""
    if getattr(config.option, "dist", "no") in ("loadfile", "loadscope"):
        config.option.loadscopereorder = False
    workers = config.workerinput["workercount"] if hasattr(config, "workerinput") else 1
    if workers > 1:
        try:
            import torch
        except ImportError:
            return
        torch.set_num_threads(max(1, (os.cpu_count() or 1) // workers))


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--cpu-durations", type=int, default=None, metavar="N",
                     help="report the N tests that took the most CPU seconds (setup, call and teardown; the "
                          "process's threads and its waited-for subprocesses; 0: all) and the suite's total: on a "
                          "shared machine, unlike --durations' wall seconds, a cost that load does not inflate")


def cpu_seconds() -> float:
    """CPU seconds (user + system) of this process's threads and of the subprocesses it has waited for."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


CPU_START = pytest.StashKey[float]()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item: pytest.Item):
    if item.config.getoption("--cpu-durations") is not None:
        item.stash[CPU_START] = cpu_seconds()
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """The teardown report carries the test's CPU seconds (as a user property: it reaches the xdist controller)."""
    if call.when == "teardown" and CPU_START in item.stash:
        item.user_properties.append(("cpu_seconds", cpu_seconds() - item.stash[CPU_START]))
    yield


def pytest_terminal_summary(terminalreporter, config: pytest.Config) -> None:
    count = config.getoption("--cpu-durations")
    if count is None:
        return
    costs = [(dict(report.user_properties)["cpu_seconds"], report.nodeid)
             for reports in terminalreporter.stats.values() for report in reports
             if getattr(report, "when", None) == "teardown" and "cpu_seconds" in dict(report.user_properties)]
    costs.sort(reverse=True)
    files: dict[str, float] = {}
    for seconds, nodeid in costs:
        files[nodeid.split("::")[0]] = files.get(nodeid.split("::")[0], 0.0) + seconds
    terminalreporter.write_sep("=", f"CPU seconds: {sum(s for s, _ in costs):.1f} in {len(costs)} tests")
    for seconds, name in (costs[:count] if count else costs):
        terminalreporter.write_line(f"{seconds:8.1f}  {name}")
    terminalreporter.write_sep("-", "per file")
    for name, seconds in sorted(files.items(), key=lambda kv: -kv[1])[:count or None]:
        terminalreporter.write_line(f"{seconds:8.1f}  {name}")


FILE_CPU_SECONDS = {
    "test_kill.py": 129, "test_isa_levels.py": 85, "test_body_fit.py": 83, "test_sweep.py": 67,
    "test_reproducible.py": 64, "test_splat_jax.py": 60, "test_xpbd.py": 57, "test_material_fit.py": 56,
    "test_demo.py": 56, "test_synth_body.py": 56, "test_splat_jax_fit.py": 50, "test_sweep_files.py": 49,
    "test_albedo_training.py": 46, "test_splat_fit_loop.py": 34, "test_eval_independent.py": 34,
    "test_xpbd_native.py": 29, "test_recon_reconstructors.py": 28, "test_newton_cloth.py": 27, "test_xpbd_synth.py": 26,
    "test_synth_capture.py": 26, "test_conformance.py": 23, "test_your_capture.py": 21,
}
"""The costliest test files' CPU seconds (``--cpu-durations`` of a whole ``make test``, 2026-12-04 evening, the files
above 20 s; docs/architecture.md, "Running the tests"), which order the files under pytest-xdist. test_demo's holds
the session's ``tiny_demo`` (about 35 s), which the first of its users builds: test_demo starts early, so the other
users (test_eval_independent, test_your_capture, ...) find it built."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under pytest-xdist, the costliest files first (:data:`FILE_CPU_SECONDS`, most first), then the other files
    holding ``slow`` tests, then the rest (each file keeps its order, and so do the files within each group): the
    long files start early and the short ones fill the workers' ends instead of one long file ending last."""
    if hasattr(config, "workerinput"):
        heavy = {item.path for item in items if item.get_closest_marker("slow")}
        items.sort(key=lambda item: (-FILE_CPU_SECONDS.get(item.path.name, 0), item.path not in heavy))


@pytest.fixture
def one_torch_thread():
    """Run the test with one torch thread (tiny tensors: threading only adds overhead on a shared machine)."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def look_at_camera(center, target, width: int, height: int, focal: float, name: str) -> Camera:
    """An OpenCV camera at ``center`` looking at ``target`` with world +Y up."""
    center, target = np.asarray(center, float), np.asarray(target, float)
    forward = target - center
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    R = np.stack([right, down, forward])
    K = np.array([[focal, 0, width / 2 + 0.25], [0, focal * 1.01, height / 2 - 0.5], [0, 0, 1]])
    return Camera(K=K, R=R, t=-R @ center, width=width, height=height, name=name)


def make_capture(n_views: int = 3, width: int = 12, height: int = 8, seed: int = 0,
                 layers: bool = True) -> Capture:
    """A random capture on a ring of cameras; with ``layers`` every optional layer is filled."""
    rng = np.random.default_rng(seed)
    views = []
    for i in range(n_views):
        a = 2 * np.pi * i / n_views
        cam = look_at_camera([3 * np.sin(a), 0.5, 3 * np.cos(a)], [0, 0.2, 0], width, height, 20.0, f"cam{i:02d}")
        kw = {}
        if layers:
            kw = dict(mask=rng.random((height, width)).astype(np.float32),
                      segmentation=rng.integers(0, 3, (height, width)).astype(np.uint8),
                      background=rng.random((height, width, 3)).astype(np.float32),
                      extras={"albedo": rng.random((height, width, 3)).astype(np.float32),
                              "depth": (1 + 3 * rng.random((height, width))).astype(np.float32)})
        views.append(View(camera=cam, image=rng.random((height, width, 3)).astype(np.float32), **kw))
    light = Light(radiance=np.array([1.5, 1.25, 1.0]), envmap=rng.random((4, 8, 3)).astype(np.float32),
                  rotation_deg=30.0) if layers else None
    return Capture(views=views, labels={0: "background", 1: "body", 2: "tshirt"}, light=light,
                   metadata={"generator": "test", "seed": seed})


def seamed_cube() -> Mesh:
    """A unit cube (8 positions, 12 triangles) with a UV atlas of 6 separate squares (24 texture vertices):
    every cube edge is a UV seam."""
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    faces, face_uv, uv = [], [], []
    for q, quad in enumerate(quads):
        u0 = q / 6
        uv += [[u0, 0], [u0 + 1 / 6, 0], [u0 + 1 / 6, 1], [u0, 1]]
        t = [4 * q + i for i in range(4)]
        faces += [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]]
        face_uv += [[t[0], t[1], t[2]], [t[0], t[2], t[3]]]
    labels = np.array([2, 2, 1, 1, 2, 1, 0, 0, 1, 2, 2, 1])
    return Mesh(v + 1e-9 * np.arange(24).reshape(8, 3), np.array(faces), np.array(uv), np.array(face_uv),
                labels, name="cube")


@pytest.fixture
def small_capture() -> Capture:
    return make_capture()


def install_distribution(site: Path, monkeypatch: pytest.MonkeyPatch, name: str, modules: dict[str, str],
                         entry_points: dict[str, str]) -> Path:
    """Install a plugin distribution ``name`` (version 0.1) into the folder ``site``, put on ``sys.path`` for the
    test: ``modules`` maps module names to their source, ``entry_points`` names to modules (group ``pgc``)."""
    import importlib

    site.mkdir(parents=True, exist_ok=True)
    for module, source in modules.items():
        (site / f"{module}.py").write_text(source)
    info = site / f"{name.replace('-', '_')}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[pgc]\n" + "".join(f"{k} = {v}\n" for k, v in entry_points.items()))
    monkeypatch.syspath_prepend(str(site))
    importlib.invalidate_caches()
    return site


@pytest.fixture(scope="session")
def tiny_demo(tmp_path_factory, pytestconfig) -> Path:
    """``pgc demo --preset tiny``, run once a session (once for all pytest-xdist workers); its users copy what
    they change."""
    from pgc.cli import main

    root = tmp_path_factory.getbasetemp()
    if hasattr(pytestconfig, "workerinput"):
        root = root.parent  # the folder all the workers of this pytest-xdist run share: one demo for all
    out, done = root / "tiny_demo" / "demo", root / "tiny_demo" / "done"
    done.parent.mkdir(exist_ok=True)
    with open(root / "tiny_demo" / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the other workers wait for the first one's demo
        if not done.exists():
            assert main(["demo", "--preset", "tiny", "--out", str(out), "--quiet"]) == 0
            done.touch()
    return out


SHORT_SIMULATION = """
[simulator.xpbd-native]
substeps = 10
iterations = 10
settle_frames = 3
"""
"""The native XPBD simulator at a third of the paper's substeps, half its iterations and 3 settle frames (a sixth of
its steps per frame), for end-to-end tests that check the pipeline runs, not how the cloth drapes."""


def fast_sweep_config(folder: Path) -> Path:
    """examples/sweeps/tiny-fast.toml with :data:`SHORT_SIMULATION`, written into ``folder``: the tests' tiny
    sweeps' settings."""
    path = folder / "tiny-fast-short-simulation.toml"
    fast = Path(__file__).parents[1] / "examples" / "sweeps" / "tiny-fast.toml"
    path.write_text(fast.read_text() + SHORT_SIMULATION)
    return path


@pytest.fixture(scope="session")
def default_scene_renderer():
    """The scene renderer of the default configuration (Mitsuba), as ``pgc synth`` without ``--config`` uses."""
    from pgc.config import load
    from pgc.synth.render import scene_renderer

    return scene_renderer(load(require_available=False))


@pytest.fixture(scope="session")
def default_body_model():
    """The body model of the default configuration (Anny), as ``pgc synth`` without ``--config`` uses."""
    from pgc.config import load

    return load(require_available=False).create("body_model")


FAKE_PLUGINS = {
    "fakeplug_ok": '''
from pgc.registry import ImplementationSpec, hookimpl
from pgc.roles.filter import Filter
import numpy as np


class Identity(Filter):
    """Low-pass that returns the image (a trivially conformant filter)."""

    def lowpass(self, image, alpha, kernel_size):
        return np.asarray(image, dtype=np.float32).copy()


@hookimpl
def pgc_register_implementations():
    return [ImplementationSpec(role="filter", name="tmp-ok", factory="fakeplug_ok:Identity",
                               description="identity filter from a temporary distribution", requires=("numpy",)),
            ImplementationSpec(role="filter", name="tmp-badfactory", factory="fakeplug_ok_impl_gone:X",
                               description="factory module that fails on import")]
''',
    "fakeplug_missing": '''
from pgc.registry import ImplementationSpec, hookimpl


@hookimpl
def pgc_register_implementations():
    return [ImplementationSpec(role="filter", name="tmp-missing", factory="fakeplug_missing:Nope",
                               description="needs a module that is not installed",
                               requires=("numpy", "pgc_module_that_does_not_exist"), extra="nonexistent")]
''',
    "fakeplug_broken": '''
raise ImportError("fakeplug_broken needs libfoo.so.3")
''',
    "fakeplug_dup": '''
from pgc.registry import ImplementationSpec, hookimpl


@hookimpl
def pgc_register_implementations():
    return [ImplementationSpec(role="filter", name="tmp-ok", factory="fakeplug_ok:Identity",
                               description="a second 'tmp-ok': a conflict")]
''',
}
FAKE_DIST = "tmp-pgc-plugins"
FAKE_ENTRY_POINTS = {"tmpok": "fakeplug_ok", "tmpmissing": "fakeplug_missing", "tmpbroken": "fakeplug_broken",
                     "tmpzdup": "fakeplug_dup"}
"""Entry-point name -> module; plugins load in name order, so the duplicate comes after the original."""


@pytest.fixture
def fake_distribution(tmp_path, monkeypatch):
    """A real installed distribution in a temporary folder on sys.path (a *.dist-info with entry points):
    one good plugin, one with a missing dependency, one that raises on import, one duplicate.
    Returns the folder (put it on PYTHONPATH for subprocesses)."""
    import sys

    yield install_distribution(tmp_path / "site", monkeypatch, FAKE_DIST, FAKE_PLUGINS, FAKE_ENTRY_POINTS)
    for module in FAKE_PLUGINS:
        sys.modules.pop(module, None)
