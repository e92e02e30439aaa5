"""The same inputs and config give byte-identical outputs: assets from `pgc reconstruct`, runs from
`pgc animate`, and the stages that run on several threads (Open3D's Poisson solve, the Mitsuba material fit)
whatever the thread count."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from conftest import seamed_cube
from pgc.cli import main
from pgc.io.asset import write_asset

TINY = """
[reconstructor]
use = ["visual_hull"]
[simulator]
use = ["xpbd-native", "xpbd-torch"]
[stages.fit_splats]
iterations = 30
converge_every = 10
select_count = false
select_sh = false
max_sh_degree = 0
[stages.base_color]
texture_size = 32
num_views = 2
[stages.material]
max_iterations = 3
max_image_side = 32
eval_spp = 4
"""


def hashes(folder: Path, skip: tuple[str, ...] = (".pgc.lock", "timings.json")) -> dict[str, str]:
    """sha256 of every output file below ``folder`` (relative names); stage caches, the lock and the wall-clock
    timings (``timings.json``, a measurement of each run) left out."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name not in skip
            and "stages" not in p.relative_to(folder).parts}


def test_an_asset_written_twice_is_byte_identical(tmp_path):
    from test_hostile import tiny_asset

    write_asset(tmp_path / "a", tiny_asset())
    write_asset(tmp_path / "b", tiny_asset())
    assert hashes(tmp_path / "a") == hashes(tmp_path / "b") and len(hashes(tmp_path / "a")) >= 6


def test_two_animate_runs_give_identical_trajectories(tmp_path, capsys):
    from test_hostile import tiny_asset

    write_asset(tmp_path / "asset", tiny_asset())
    v = seamed_cube().vertices
    np.savez(tmp_path / "m.npz", vertices=np.stack([v + [0, 0.002 * t, 0] for t in range(6)]),
             faces=seamed_cube().faces, fps=30.0)
    (tmp_path / "c.toml").write_text(TINY)
    for run in ("r1", "r2"):
        assert main(["animate", str(tmp_path / "asset"), "--motion", str(tmp_path / "m.npz"), "--out",
                     str(tmp_path / run), "--config", str(tmp_path / "c.toml"), "--quiet"]) == 0
    a, b = hashes(tmp_path / "r1"), hashes(tmp_path / "r2")
    assert a["garment.npz"] == b["garment.npz"] and a["body.npz"] == b["body.npz"]


@pytest.mark.slow
def test_two_reconstructions_of_one_capture_are_byte_identical(tmp_path, capsys):
    assert main(["synth", str(tmp_path / "cap"), "--preset", "tiny", "--views", "4", "--resolution", "32",
                 "--spp", "4"]) == 0
    (tmp_path / "c.toml").write_text(TINY)
    for out in ("a1", "a2"):
        code = main(["reconstruct", str(tmp_path / "cap"), "--out", str(tmp_path / out), "--config",
                     str(tmp_path / "c.toml"), "--quiet"])
        assert code == 0, capsys.readouterr().err
    assert hashes(tmp_path / "a1") == hashes(tmp_path / "a2")


def test_poisson_surface_is_identical_from_call_to_call():
    """Open3D's multi-threaded solve changes the mesh from call to call (and with the thread count); the
    reconstructor's solve does not."""
    pytest.importorskip("open3d")
    from pgc_open3d.reconstruct import poisson_surface

    rng = np.random.default_rng(0)
    normals = rng.normal(size=(20000, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    points = normals * (1.0 + 0.2 * np.sin(3.0 * normals[:, :1]))  # a bumpy sphere, outward normals
    meshes = [poisson_surface(points, normals, 7, 0.02) for _ in range(3)]
    assert len(meshes[0][1]) > 1000
    for v, f in meshes[1:]:
        assert v.tobytes() == meshes[0][0].tobytes() and f.tobytes() == meshes[0][1].tobytes()


def test_material_fit_is_identical_whatever_the_thread_count(monkeypatch):
    """Each shard's gradient is summed on one Dr.Jit thread and the shards in a fixed order: the fitted
    material and light are the same bytes with the shards rendered one after the other in this process (one
    core allotted) or in two processes (two cores), whatever Dr.Jit's pool size, and from one fit to the next."""
    pytest.importorskip("mitsuba")
    from test_material_fit import FAST, synthetic_capture

    from pgc.testing.pbr_scenes import checker_texture, folded_sheet
    from pgc.registry import default_registry
    from pgc.types import Material
    from pgc_mitsuba.runtime import mitsuba

    mitsuba()
    import drjit as dr

    texture = checker_texture(32)
    capture = synthetic_capture(Material("pgc-sheen", {"roughness": 0.5}, texture), n_views=4, size=48, spp=16)
    renderer = default_registry().create("pbr_renderer", "mitsuba", {"spp": 4, "max_depth": 2})
    # several blocks per film; two processes even for this small film when two cores are allotted
    settings = FAST.model_copy(update={"max_iterations": 10, "max_image_side": 48, "parallel_min_pixels": 0,
                                       "polish": True, "polish_iterations": 2, "polish_spp": 8})
    import pgc_mitsuba.shards as shards

    started = []

    class CountedWorker(shards.Worker):  # the real worker process, counted
        def __init__(self, *args):
            started.append(1)
            super().__init__(*args)

    monkeypatch.setattr(shards, "Worker", CountedWorker)
    previous, fits, workers = dr.thread_count(), [], []
    try:
        for threads in (2, 1, 2):
            dr.set_thread_count(threads)
            monkeypatch.setenv("OMP_NUM_THREADS", str(threads))
            fit = renderer.fit(capture, folded_sheet(n=16), Material("pgc-sheen", {}, texture), settings)
            fits.append((fit.light.radiance.tobytes(), repr(sorted(fit.material.params.items()))))
            workers.append(len(started))
    finally:
        dr.set_thread_count(previous)
    assert workers == [1, 1, 2]  # two cores: a worker process; one core: the shards in turn here
    assert fits[0] == fits[1] == fits[2]
