"""The stage cache: content keys, reuse, recompute on change, no half-written stage after a crash."""

import json

import numpy as np
import pytest

from pgc.pipeline.cache import StageCache, array_key, asset_key, content_key, file_key


def test_content_key_is_stable_and_order_free():
    assert content_key({"a": 1, "b": [1, 2]}) == content_key({"b": [1, 2], "a": 1})
    assert content_key({"a": 1}) != content_key({"a": 2})


def test_file_and_array_keys_follow_content(tmp_path):
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "x.txt").write_text("one")
    k1 = file_key(tmp_path / "d")
    (tmp_path / "d" / "x.txt").write_text("two")
    assert file_key(tmp_path / "d") != k1
    a = np.arange(6.0)
    assert array_key(a) == array_key(a.copy()) != array_key(a.reshape(2, 3)) != array_key(a.astype(np.float32))


def test_stage_is_reused_when_the_key_matches_and_recomputed_when_it_changes(tmp_path):
    cache = StageCache(tmp_path)
    calls = []

    def compute(folder):
        calls.append(1)
        (folder / "v.json").write_text(json.dumps(len(calls)))
        return len(calls), {"n": len(calls)}

    def load(folder):
        return json.loads((folder / "v.json").read_text())

    first = cache.run("s", "k1", compute, load)
    again = cache.run("s", "k1", compute, load)
    assert (first.value, first.cached, again.value, again.cached) == (1, False, 1, True)
    changed = cache.run("s", "k2", compute, load)
    assert (changed.value, changed.cached) == (2, False)
    assert cache.figures("s") == {"n": 2}


def test_a_crash_inside_a_stage_leaves_the_previous_result_intact(tmp_path):
    cache = StageCache(tmp_path)

    def good(folder):
        (folder / "v.txt").write_text("good")
        return "good", {}

    cache.run("s", "k1", good, lambda f: (f / "v.txt").read_text())

    def crash(folder):
        (folder / "v.txt").write_text("half")
        raise RuntimeError("killed")

    with pytest.raises(RuntimeError):
        cache.run("s", "k2", crash, lambda f: (f / "v.txt").read_text())
    assert cache.cached_key("s") == "k1"
    assert (cache.folder("s") / "v.txt").read_text() == "good"
    assert [p.name for p in tmp_path.iterdir()] == ["s"]  # no temporary folder left behind


def test_the_asset_key_follows_the_asset_files_not_the_settings_or_timings_it_recorded(tmp_path):
    """A render setting changed between runs rewrites the asset's manifest (it records the run config); the
    simulations and renders keyed on the asset must not be recomputed for that, but must be for new files."""
    manifest = {"schema_version": 1, "files": {"garment": "garment.obj"}, "hashes": {"garment": "ab12"},
                "heldout_views": ["cam007"], "config": {"stages": {"render": {"outline_fade": 1.0}}},
                "figures": {"seconds": {"mesh": 61.2}}}
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    key = asset_key(tmp_path)
    manifest.update(config={"stages": {"render": {"outline_fade": 0.0}}}, figures={"seconds": {"mesh": 58.0}})
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    assert asset_key(tmp_path) == key
    for field, value in (("hashes", {"garment": "cd34"}), ("heldout_views", ["cam015"])):
        changed = dict(manifest, **{field: value})
        (tmp_path / "manifest.json").write_text(json.dumps(changed))
        assert asset_key(tmp_path) != key, field


def _scene_renderer_config(**options):
    from pgc.config import resolve

    return resolve({"scene_renderer": {"use": "mitsuba", "mitsuba": options}}, require_available=False)


def test_the_scene_renderer_is_part_of_the_ground_truth_key(tmp_path):
    from pgc.pipeline.evaluate import ground_truth_key

    run, capture = tmp_path / "run", tmp_path / "capture"
    (capture / "ground_truth").mkdir(parents=True)
    run.mkdir()
    for path in (run / "garment.npz", run / "body.npz", capture / "ground_truth" / "scene.json"):
        path.write_text(path.name)

    def key(**options):
        return ground_truth_key(run, capture, ["cam_000"], _scene_renderer_config(**options))

    assert key() == key(max_depth=8) == key()  # the default, written out or not: one key
    assert key(max_depth=3) not in (key(), key(max_depth=4))
    version = _scene_renderer_config().role_key("scene_renderer")["version"]
    assert version is not None  # the providing distribution's version is part of it


def test_the_demo_capture_is_regenerated_when_the_scene_renderer_changes(tmp_path, monkeypatch):
    pytest.importorskip("mitsuba")
    import pgc.synth.generate as generate_mod
    from pgc.pipeline.demo import synthetic_capture

    rendered = []

    def generate(folder, preset, seed, reporter, renderer, body_model):
        folder.mkdir(parents=True, exist_ok=True)
        rendered.append(renderer.options.max_depth)

    monkeypatch.setattr(generate_mod, "generate", generate)
    folder = tmp_path / "capture"
    assert synthetic_capture(folder, "tiny", 0, _scene_renderer_config()) is True
    assert synthetic_capture(folder, "tiny", 0, _scene_renderer_config(max_depth=8)) is False  # same renderer
    assert synthetic_capture(folder, "tiny", 0, _scene_renderer_config(max_depth=3)) is True
    assert rendered == [8, 3]
