"""Ground-truth frames kept across runs (pgc.pipeline.truth_cache): a frame is rendered once for equal inputs and
read back with the bytes a whole-sequence render gives; the key follows every input; frame 0, the capture pose
shared by every motion, is rendered once."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from pgc.pipeline.truth_cache import TruthFrameCache, camera_identity, light_at
from pgc.types import Camera

TINY_CONFIG = Path(__file__).resolve().parents[1] / "pgc" / "presets" / "demo_tiny.toml"


def _camera(name: str = "c0", shift: float = 0.0) -> Camera:
    return Camera(K=[[40.0, 0, 16], [0, 40.0, 16], [0, 0, 1]], R=np.eye(3), t=[shift, 0.0, 2.0], width=32, height=32,
                  name=name)


def test_the_key_follows_every_input(tmp_path):
    cache = TruthFrameCache(tmp_path, "scene")
    rng = np.random.default_rng(0)
    g, b = rng.normal(size=(50, 3)), rng.normal(size=(40, 3))
    light = {"kind": "envmap", "sha256": "ab", "frames": [0, 5], "rotation_deg": [10.0, 20.0]}
    base = cache.key(g, b, [_camera()], light_at(light, 0), 0)
    assert base == cache.key(g.copy(), b.copy(), [_camera()], light_at(light, 0), 0)
    nudged = g.copy()
    nudged[7, 1] = np.nextafter(nudged[7, 1], np.inf)  # one float64 ulp
    others = [cache.key(nudged, b, [_camera()], light_at(light, 0), 0),
              cache.key(g, b + 1e-12, [_camera()], light_at(light, 0), 0),
              cache.key(g, b, [_camera(shift=1e-9)], light_at(light, 0), 0),
              cache.key(g, b, [_camera(name="c1")], light_at(light, 0), 0),
              cache.key(g, b, [_camera()], light_at(light, 5), 0),
              cache.key(g, b, [_camera()], {"kind": "capture"}, 0),
              cache.key(g, b, [_camera()], light_at(light, 0), 1),
              TruthFrameCache(tmp_path, "other scene").key(g, b, [_camera()], light_at(light, 0), 0)]
    assert len({base, *others}) == len(others) + 1
    assert camera_identity(_camera())[0] == "c0"


def test_a_kept_frame_reads_back_whole_and_no_partial_file_stays(tmp_path):
    cache = TruthFrameCache(tmp_path / "frames", "scene")
    frame = {"color": np.random.default_rng(1).random((2, 4, 5, 3)).astype(np.float32),
             "segmentation": np.arange(40, dtype=np.uint8).reshape(2, 4, 5)}
    assert cache.load("k") is None
    cache.store("k", frame)
    back = cache.load("k")
    assert back.keys() == frame.keys() and all(np.array_equal(back[k], frame[k]) and back[k].dtype == frame[k].dtype
                                               for k in frame)
    assert [p.name for p in (tmp_path / "frames").iterdir()] == ["k.npz"]
    off = TruthFrameCache(None, "")
    off.store("k", frame)
    assert off.load("k") is None


def test_the_cache_is_off_with_the_capture_cache(monkeypatch, tmp_path):
    from pgc.pipeline.truth_cache import frame_cache_root

    monkeypatch.setenv("PGC_CAPTURE_CACHE", "off")
    assert frame_cache_root() is None
    monkeypatch.setenv("PGC_CAPTURE_CACHE", str(tmp_path / "c"))
    assert frame_cache_root() == tmp_path / "c" / "frames"


def count_rendered_frames(monkeypatch) -> list[int]:
    """Wrap :func:`pgc.synth.frames.render_frames`; the returned list gets the number of frames of each call."""
    import pgc.synth.frames as frames_mod

    real, rendered = frames_mod.render_frames, []

    def counted(*args, **kwargs):
        out = real(*args, **kwargs)
        rendered.append(len(out))
        return out

    monkeypatch.setattr(frames_mod, "render_frames", counted)
    return rendered


@pytest.mark.slow
def test_truth_frames_are_rendered_once_with_the_bytes_of_a_whole_sequence(tiny_demo, tmp_path, monkeypatch):
    """Two motions of the tiny demo: the first renders every frame, the second all but frame 0 (the capture pose);
    a new folder renders nothing; every frame equals the demo's own truth, rendered whole with the cache off."""
    from pgc import config
    from pgc.events import Reporter
    from pgc.pipeline.evaluate import rendered_frames, synthetic_ground_truth

    monkeypatch.setenv("PGC_CAPTURE_CACHE", str(tmp_path / "cache"))
    rendered = count_rendered_frames(monkeypatch)
    cfg = config.load(TINY_CONFIG)
    runs = sorted((tiny_demo / "runs").iterdir())[:2]
    for copy in ("a", "b"):
        for run in runs:
            mine = tmp_path / copy / run.name
            shutil.copytree(run, mine, ignore=shutil.ignore_patterns("gt"))
            meta, frames = rendered_frames(mine)
            capture = Path(json.loads((mine / "run.json").read_text())["capture"])
            truth = synthetic_ground_truth(mine, capture, frames, meta["cameras"], cfg,
                                           Reporter.silent())
            demo_truth = next(p for p in (run / "gt").iterdir() if (p / "light.json").is_file()
                              and json.loads((p / "light.json").read_text()) == {"kind": "capture"})
            for t, frame in zip(frames, truth):
                whole = np.load(demo_truth / f"frame_{t:04d}_spp{cfg.stage('eval').gt_spp}.npz")
                assert all(np.array_equal(frame[k], whole[k]) for k in whole.files)
    n = len(frames)
    assert rendered == [n, n - 1]  # folder b: every frame read back
    assert len(list((tmp_path / "cache" / "frames").glob("*.npz"))) == 2 * n - 1


@pytest.mark.slow
def test_an_interrupted_truth_keeps_the_frames_it_finished(tiny_demo, tmp_path, monkeypatch):
    """Each truth frame is kept as soon as it is rendered: an eval stopped during its second frame keeps the first,
    and the rerun renders only the others."""
    import pgc.synth.frames as frames_mod
    from pgc import config
    from pgc.events import Reporter
    from pgc.pipeline.evaluate import rendered_frames, synthetic_ground_truth

    monkeypatch.setenv("PGC_CAPTURE_CACHE", str(tmp_path / "cache"))
    cfg = config.load(TINY_CONFIG)
    run = sorted((tiny_demo / "runs").iterdir())[0]
    mine = tmp_path / run.name
    shutil.copytree(run, mine, ignore=shutil.ignore_patterns("gt"))
    meta, frames = rendered_frames(mine)
    capture = Path(json.loads((mine / "run.json").read_text())["capture"])
    real_colour, views = frames_mod.converged_color, []

    def stopped_in_the_second_frame(*args, **kwargs):
        views.append(1)
        if len(views) > len(meta["cameras"]):
            raise KeyboardInterrupt
        return real_colour(*args, **kwargs)

    monkeypatch.setattr(frames_mod, "converged_color", stopped_in_the_second_frame)
    with pytest.raises(KeyboardInterrupt):
        synthetic_ground_truth(mine, capture, frames, meta["cameras"], cfg, Reporter.silent())
    assert len(list((tmp_path / "cache" / "frames").glob("*.npz"))) == 1
    monkeypatch.setattr(frames_mod, "converged_color", real_colour)
    rendered = count_rendered_frames(monkeypatch)
    truth = synthetic_ground_truth(mine, capture, frames, meta["cameras"], cfg, Reporter.silent())
    assert rendered == [len(frames) - 1] and len(truth) == len(frames)
