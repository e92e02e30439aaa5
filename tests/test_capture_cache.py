"""The capture cache (pgc.pipeline.capture_cache): a synthetic capture generated once serves new folders with the
same bytes; an interrupted generation leaves nothing behind; the key follows the generator's source."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from pgc.pipeline.capture_cache import KEY_FILE, cached_capture, source_key


def files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_demo_capture_is_generated_once_and_copied_byte_for_byte(tmp_path, monkeypatch):
    pytest.importorskip("mitsuba")
    import pgc.synth.generate as generate_mod
    from pgc.config import resolve
    from pgc.pipeline.demo import synthetic_capture

    monkeypatch.setenv("PGC_CAPTURE_CACHE", str(tmp_path / "cache"))
    real, calls = generate_mod.generate, []

    def counted(folder, **kwargs):
        calls.append(Path(folder))
        return real(folder, **kwargs)

    monkeypatch.setattr(generate_mod, "generate", counted)
    cfg = resolve(None, None)
    assert synthetic_capture(tmp_path / "a" / "capture", "tiny", 1, cfg) is True
    assert synthetic_capture(tmp_path / "b" / "capture", "tiny", 1, cfg) is True
    assert synthetic_capture(tmp_path / "b" / "capture", "tiny", 1, cfg) is False
    assert len(calls) == 1 and calls[0].parent == tmp_path / "cache"  # generated into the cache, once
    a, b = files(tmp_path / "a" / "capture"), files(tmp_path / "b" / "capture")
    assert a == b and "transforms.json" in a and KEY_FILE in a
    entries = [p for p in (tmp_path / "cache").iterdir() if p.is_dir()]
    assert len(entries) == 1 and not entries[0].name.startswith(".")


def test_an_interrupted_generation_leaves_no_entry(tmp_path, monkeypatch):
    monkeypatch.setenv("PGC_CAPTURE_CACHE", str(tmp_path / "cache"))

    def interrupted(path: Path) -> None:
        path.mkdir(parents=True)
        (path / "images").mkdir()
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        cached_capture(tmp_path / "capture", ["scene", 0], interrupted)
    assert not [p for p in (tmp_path / "cache").iterdir() if p.is_dir() and not p.name.startswith(".")]
    assert not (tmp_path / "capture" / KEY_FILE).exists()

    def complete(path: Path) -> None:
        path.mkdir(parents=True)
        (path / "transforms.json").write_text("{}")

    assert cached_capture(tmp_path / "capture", ["scene", 0], complete) is True
    assert (tmp_path / "capture" / "transforms.json").read_text() == "{}"


def test_the_cache_off_generates_in_place(tmp_path, monkeypatch):
    monkeypatch.setenv("PGC_CAPTURE_CACHE", "off")
    made = []

    def make(path: Path) -> None:
        made.append(path)
        path.mkdir(parents=True, exist_ok=True)

    assert cached_capture(tmp_path / "capture", ["scene"], make) is True
    assert cached_capture(tmp_path / "capture", ["scene"], make) is False
    assert cached_capture(tmp_path / "capture", ["scene", 1], make) is True
    assert made == [tmp_path / "capture"] * 2


def test_the_key_follows_the_source_of_the_renderer_package(tmp_path):
    package = tmp_path / "fake_renderer"
    package.mkdir()
    (package / "__init__.py").write_text("class Renderer:\n    pass\n")

    def renderer_class() -> type:
        spec = importlib.util.spec_from_file_location("fake_renderer", package / "__init__.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules["fake_renderer"] = module
        spec.loader.exec_module(module)
        return module.Renderer

    before = source_key(renderer_class())
    assert source_key(renderer_class()) == before
    (package / "shading.py").write_text("ROUGHNESS = 0.5\n")
    assert source_key(renderer_class()) != before
    sys.modules.pop("fake_renderer")
