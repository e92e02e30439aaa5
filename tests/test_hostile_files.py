"""Hostile files, paths and settings: writers that meet a device, a pipe or a link; asset manifests naming
files outside the asset; settings that validate but cannot be meant; small files asking for unbounded work
(pgc.io.limits); COLMAP models; captures nothing can be reconstructed from. Each is one clear error naming the
file and the field (exit 2 through the commands), and nothing already written changes."""

from __future__ import annotations

import errno
import json
import os
import shutil
import socket
import stat
import struct
import typing
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pydantic
import pytest

from pgc.errors import PGCConfigError, PGCDataError
from pgc.io import limits
from pgc.io.asset import file_hash, read_asset, write_asset
from pgc.io.atomic import write_json, write_text
from pgc.io.capture import read_capture, write_capture
from test_hostile import World, capture_copy, pgc, snapshot, tiny_asset, world  # noqa: F401 (fixture)


def one_error(argv: list, words: list[str], capsys, *folders: Path) -> None:
    """The command fails with exit 2 and one ``pgc CMD: error:`` line holding ``words``; ``folders`` unchanged."""
    before = snapshot(*folders)
    code, err = pgc(argv, capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"pgc {argv[0]}: error: "), err
    for word in words:
        assert word in err, (word, err)
    assert snapshot(*folders) == before


def char_device(path: str) -> bool:
    return stat.S_ISCHR(os.stat(path).st_mode)


# ---- writers: devices, pipes, sockets, links, folders -------------------------------------------------------
def test_writing_to_dev_null_writes_in_place_and_keeps_the_device():
    assert char_device("/dev/null")
    write_json("/dev/null", {"a": 1})
    write_text("/dev/null", "x")
    assert char_device("/dev/null")


def test_writing_to_dev_full_is_a_clear_no_space_error_and_keeps_the_device():
    if not os.path.exists("/dev/full") or not char_device("/dev/full"):
        pytest.skip("no /dev/full")
    with pytest.raises(OSError) as exc:
        write_json("/dev/full", {"a": 1})
    assert exc.value.errno == errno.ENOSPC and exc.value.filename == "/dev/full"
    assert char_device("/dev/full")


@pytest.mark.parametrize("kind", ["fifo", "socket", "folder"])
def test_a_writer_refuses_a_node_that_is_no_file(kind, tmp_path):
    node = tmp_path / f"out.{kind}"
    if kind == "fifo":
        os.mkfifo(node)
    elif kind == "socket":
        sock = socket.socket(socket.AF_UNIX)
        sock.bind(str(node))
    else:
        node.mkdir()
    mode = os.stat(node).st_mode
    with pytest.raises(PGCDataError, match={"fifo": "named pipe", "socket": "a socket", "folder": "is a folder"}[kind]):
        write_json(node, {"a": 1})
    assert os.stat(node).st_mode == mode and sorted(os.listdir(tmp_path)) == [node.name]


def test_a_symlink_to_a_file_keeps_the_link_and_replaces_the_target(tmp_path):
    (tmp_path / "real.json").write_text("old")
    (tmp_path / "link.json").symlink_to(tmp_path / "real.json")
    write_json(tmp_path / "link.json", {"b": 2})
    assert (tmp_path / "link.json").is_symlink() and json.loads((tmp_path / "real.json").read_text()) == {"b": 2}
    assert sorted(os.listdir(tmp_path)) == ["link.json", "real.json"]


def test_a_dangling_symlink_is_refused(tmp_path):
    (tmp_path / "link.json").symlink_to(tmp_path / "elsewhere" / "x.json")
    with pytest.raises(PGCDataError, match="symbolic link to .*does not exist"):
        write_json(tmp_path / "link.json", {})
    assert not (tmp_path / "elsewhere").exists()


def test_a_file_where_a_folder_is_meant_is_refused(tmp_path):
    (tmp_path / "file").write_text("keep")
    with pytest.raises(PGCDataError, match="lies below .*file, which is not a folder"):
        write_json(tmp_path / "file" / "sub" / "x.json", {})
    with pytest.raises(PGCDataError, match="file: is not a folder"):
        write_asset(tmp_path / "file", tiny_asset())
    from conftest import make_capture

    with pytest.raises(PGCDataError, match="file: is not a folder"):
        write_capture(tmp_path / "file", make_capture(n_views=2, width=4, height=3))
    assert (tmp_path / "file").read_text() == "keep"


def test_a_folder_where_an_asset_file_is_meant_is_refused(tmp_path):
    (tmp_path / "asset" / "light.json").mkdir(parents=True)
    with pytest.raises(PGCDataError, match="light.json: is a folder"):
        write_asset(tmp_path / "asset", tiny_asset())
    assert not (tmp_path / "asset" / "manifest.json").exists()


@pytest.mark.parametrize("target", ["fifo", "dev_null", "dev_full"])
def test_export_to_a_fifo_or_through_a_link_to_a_device(target, world, tmp_path, capsys):
    out = tmp_path / "out.glb"
    if target == "fifo":
        os.mkfifo(out)
        one_error(["export", world.asset, "--format", "gltf", "--out", out], [str(out), "named pipe"], capsys,
                  world.root)
        assert stat.S_ISFIFO(os.stat(out).st_mode)
        return
    pytest.importorskip("pygltflib")
    device = f"/dev/{target[4:]}"
    if not os.path.exists(device) or not char_device(device):
        pytest.skip(f"no {device}")
    out.symlink_to(device)
    if target == "dev_null":
        code, err = pgc(["export", world.asset, "--format", "gltf", "--out", out], capsys)
        assert code == 0, err
    else:
        one_error(["export", world.asset, "--format", "gltf", "--out", out], [str(out), "No space left on device"],
                  capsys, world.root)
    assert out.is_symlink() and char_device(device) and os.listdir(tmp_path) == ["out.glb"]


# ---- asset manifests: files outside the asset ----------------------------------------------------------------
def asset_copy(tmp: Path, w: World) -> tuple[Path, dict]:
    asset = tmp / "asset"
    shutil.copytree(w.asset, asset)
    return asset, json.loads((asset / "manifest.json").read_text())


def _outside(asset: Path, m: dict) -> str:
    other = asset.parent / "other"
    other.mkdir()
    shutil.copy(asset / "light.json", other / "light.json")
    m["files"]["light"] = "../other/light.json"
    return "files.light"


def _absolute(asset: Path, m: dict) -> str:
    m["files"]["light"] = str(asset / "light.json")
    return "files.light"


def _link_outside(asset: Path, m: dict) -> str:
    shutil.copy(asset / "light.json", asset.parent / "light.json")
    (asset / "light.json").unlink()
    (asset / "light.json").symlink_to(asset.parent / "light.json")
    return "leads outside"


def _not_a_string(asset: Path, m: dict) -> str:
    m["files"]["light"] = 3
    return "files.light"


def _base_color_outside(asset: Path, m: dict) -> str:
    mat = json.loads((asset / "material.json").read_text())
    mat["base_color"] = "../albedo.exr"
    shutil.copy(asset / "albedo.exr", asset.parent / "albedo.exr")
    (asset / "material.json").write_text(json.dumps(mat))
    m["hashes"]["material"] = file_hash(asset / "material.json")
    return "base_color"


def _base_color_unlisted(asset: Path, m: dict) -> str:
    mat = json.loads((asset / "material.json").read_text())
    mat["base_color"] = "copy.exr"
    shutil.copy(asset / "albedo.exr", asset / "copy.exr")
    (asset / "material.json").write_text(json.dumps(mat))
    m["hashes"]["material"] = file_hash(asset / "material.json")
    return "not among the files"


def _deep_light(asset: Path, m: dict) -> str:
    (asset / "light.json").write_text('{"radiance": ' + "[" * 100_000 + "]" * 100_000 + "}")
    m["hashes"]["light"] = file_hash(asset / "light.json")
    return "nested"


ASSET_EDITS = {"outside": _outside, "absolute": _absolute, "link_outside": _link_outside,
               "not_a_string": _not_a_string, "base_color_outside": _base_color_outside,
               "base_color_unlisted": _base_color_unlisted, "deep_light": _deep_light}


@pytest.mark.parametrize("edit", list(ASSET_EDITS))
def test_asset_files_must_lie_inside_the_asset(edit, world, tmp_path, capsys):
    asset, manifest = asset_copy(tmp_path, world)
    word = ASSET_EDITS[edit](asset, manifest)
    (asset / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(PGCDataError, match=word):
        read_asset(asset)
    one_error(["info", asset], [str(asset), word], capsys, tmp_path, world.root)


# ---- settings: integers that are no integers, unbounded counts -------------------------------------------------
CONFIG_CASES = {
    "bool_iterations": ("[stages.fit_splats]\niterations = true\n", ["iterations", "[1, 1000000]", "boolean"]),
    "huge_float_iterations": ("[stages.fit_splats]\niterations = 1e30\n", ["iterations", "[1, 1000000]", "float"]),
    "whole_float": ("[stages.fit_splats]\niterations = 3000.0\n", ["iterations", "float"]),
    "huge_int": ("[stages.fit_splats]\nmin_gaussians = 9223372036854775807\n",
                 ["min_gaussians", "[1, 10000000]"]),
    "quoted_int": ("[stages.material]\nspp = '4'\n", ["spp", "string"]),
    "negative_seed": ("[stages.material]\nseed = -1\n", ["seed", "[0, 4294967295]"]),
    "nested_float": ("[stages.render.kernel]\nmode = 'fixed'\nsize = 2.5\n", ["kernel.size", "float"]),
    "list_item_bool": ("[stages.render.kernel]\nsizes = [3, true]\n", ["kernel.sizes", "every item", "boolean"]),
    "texture_fraction": ("[stages.base_color]\ntexture_size = 64.7\n", ["texture_size", "[16, 8192]"]),
    "endless_seconds": ("[stages.animate]\nseconds = 1e12\n", ["seconds", "600"]),
    "kernel_sizes_item_huge": ("[stages.render.kernel]\nmode = 'error'\nsizes = [3, 1000001]\n",
                               ["kernel.sizes", "every item", "[1, 4095]", "out of range"]),
    "xpbd_substeps_huge": ("[simulator]\nuse = 'xpbd-native'\n[simulator.xpbd-native]\nsubsteps = 1000000\n",
                           ["option 'substeps'", "[1, 1000]", "out of range"]),
    "two_bad_options_one_line": ("[simulator]\nuse = 'xpbd-native'\n[simulator.xpbd-native]\niterations = 0\n"
                                 "candidates = 100000\n", ["option 'iterations'", "; option 'candidates'",
                                                            "[1, 256]", "; valid options: "]),
    "deep_toml": ("a = " + "[" * 100_000 + "]" * 100_000 + "\n", ["bad.toml", "nested"]),
    "huge_toml": ("# " + "x" * (limits.MAX_CONFIG_BYTES + 1) + "\n", ["bad.toml", "bytes"]),
}


@pytest.mark.parametrize("name", list(CONFIG_CASES))
def test_config_values_that_cannot_be_meant_are_refused(name, tmp_path, capsys):
    text, words = CONFIG_CASES[name]
    (tmp_path / "bad.toml").write_text(text)
    one_error(["config", "validate", tmp_path / "bad.toml"], ["bad.toml", *words], capsys, tmp_path)


def _int_fields(model: type[pydantic.BaseModel], prefix: str = "") -> list[tuple[str, type, str]]:
    from pgc.options import Options, _integer_kind

    out = []
    for name, field in model.model_fields.items():
        kind = _integer_kind(field.annotation)
        if kind:
            out.append((prefix + name, model, kind))
        nested = [a for a in (field.annotation, *typing.get_args(field.annotation))
                  if isinstance(a, type) and issubclass(a, Options)]
        out += [f for n in nested for f in _int_fields(n, f"{prefix}{name}.")]
    return out


def all_integer_fields() -> list[tuple[str, type, str]]:
    from pgc.stages import settings_models
    from pgc.registry import Registry

    fields = [(f"stages.{s}.{n}", m, k) for s, model in settings_models().items() for n, m, k in _int_fields(model)]
    for (role, name), impl in Registry.discover().implementations.items():
        try:
            model = impl.options_model()
        except Exception:  # an implementation whose plugin cannot load has no schema to check
            continue
        if model is not None:
            fields += [(f"{role}.{name}.{n}", m, k) for n, m, k in _int_fields(model)]
    return fields


def test_every_integer_option_of_every_schema_refuses_booleans_floats_and_huge_values():
    fields = all_integer_fields()
    assert len(fields) > 40
    for path, model, kind in fields:
        name = path.rsplit(".", 1)[1]
        for bad in (True, 1e30, 2.0, 2**63 - 1):
            value = [bad] if kind == "list" else bad
            with pytest.raises(pydantic.ValidationError, match="Input should be a valid integer in ") as exc:
                model.model_validate({name: value})
            assert name in [e["loc"][0] for e in exc.value.errors()], path  # beside any required option's error


def test_the_stage_settings_declare_and_describe_an_upper_bound_for_every_integer():
    from pgc.stages import settings_models

    for stage, model in settings_models().items():
        for name, field_model, _ in _int_fields(model):
            field = field_model.model_fields[name.rsplit(".", 1)[-1]]
            highs = [m.le for m in field.metadata if getattr(m, "le", None) is not None]
            if field_model.__module__.startswith("pgc.filtering"):
                continue  # the kernel selection belongs to the filtering package
            assert highs, (stage, name)
            assert f", {highs[0]}]" in (field.description or ""), (stage, name, field.description)


def test_the_presets_and_the_defaults_still_validate():
    from pgc import config

    presets = sorted((Path(config.__file__).parent / "presets").glob("*.toml"))
    assert presets
    for preset in presets:
        config.resolve(config.load_toml(preset), require_available=False, source=str(preset))


# ---- captures: unbounded sizes, meaningless values, degenerate views ---------------------------------------------
def _png(width: int, height: int) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 8)) + chunk(b"IEND", b"")


def _huge_exr(cap: Path, doc: dict) -> None:
    from pgc.io.images import write_exr

    write_exr(cap / "images" / "cam00.exr", np.zeros((12, 16, 3), np.float32))
    raw = (cap / "images" / "cam00.exr").read_bytes()
    key = b"dataWindow\0box2i\0" + struct.pack("<i", 16)
    at = raw.index(key) + len(key)
    (cap / "images" / "cam00.exr").write_bytes(raw[:at] + struct.pack("<4i", 0, 0, 99_999, 99_999) + raw[at + 16:])
    doc["frames"][0]["file_path"] = "images/cam00.exr"


def _same_pose(cap: Path, doc: dict) -> None:
    for frame in doc["frames"]:
        frame["transform_matrix"] = doc["frames"][0]["transform_matrix"]


def _masks(value: float):
    def mutate(cap: Path, doc: dict) -> None:
        from pgc.io.images import write_mask

        for frame in doc["frames"]:
            write_mask(cap / frame["mask_path"], np.full((12, 16), value, np.float32))
    return mutate


def _one_label(cap: Path, doc: dict) -> None:
    from pgc.io.images import write_labels

    for frame in doc["frames"]:
        write_labels(cap / frame["pgc_segmentation_path"], np.zeros((12, 16), np.uint8))


def _set_frame(key: str, value):
    def mutate(cap: Path, doc: dict) -> None:
        doc["frames"][0][key] = value
    return mutate


CAPTURE_CASES = {
    "width_fraction": (_set_frame("w", 16.7), ["frames[0]", "'w'", "whole number"]),
    "width_bool": (_set_frame("w", True), ["frames[0]", "'w'"]),
    "width_zero": (_set_frame("h", 0), ["frames[0]", "'h'"]),
    "too_many_frames": (lambda c, d: None, ["frames", "4 frames is more than the limit of 3"]),
    "deep_json": (None, ["transforms.json", "nested"]),
    "png_header_huge": (lambda c, d: (c / d["frames"][0]["file_path"]).write_bytes(_png(100_000, 100_000)),
                        ["cam00.png", "limit"]),
    "exr_header_huge": (_huge_exr, ["cam00.exr", "dataWindow", "limit"]),
    "path_outside": (_set_frame("file_path", "../elsewhere.png"), ["frames[0].file_path", "inside the capture"]),
    "path_absolute": (lambda c, d: d["frames"][0].update(file_path=str(c / d["frames"][0]["file_path"])),
                      ["frames[0].file_path", "inside the capture"]),
    "mask_outside": (lambda c, d: d["frames"][1].update(mask_path="../" + c.name + "/" + d["frames"][1]["mask_path"]),
                     ["frames[1].mask_path", "inside the capture"]),
    "one_pose": (_same_pose, ["transforms.json", "no baseline"]),
    "masks_full": (_masks(1.0), ["transforms.json", "mask_path", "foreground everywhere"]),
    "masks_empty": (_masks(0.0), ["transforms.json", "mask_path", "background everywhere"]),
    "one_label": (_one_label, ["transforms.json", "segmentation", "single label"]),
}


@pytest.mark.parametrize("name", list(CAPTURE_CASES))
def test_hostile_captures_are_refused_before_any_work(name, world, tmp_path, capsys, monkeypatch):
    cap, doc = capture_copy(tmp_path, world)
    if name == "too_many_frames":
        monkeypatch.setattr(limits, "MAX_VIEWS", 3)
    mutate, words = CAPTURE_CASES[name]
    if mutate is None:
        (cap / "transforms.json").write_text('{"frames": ' + "[" * 100_000 + "]" * 100_000 + "}")
    else:
        mutate(cap, doc)
        (cap / "transforms.json").write_text(json.dumps(doc))
    one_error(["reconstruct", cap, "--out", tmp_path / "out", "--quiet"], words, capsys, tmp_path, world.root)
    assert not (tmp_path / "out").exists()


def test_a_capture_of_too_many_pixels_together_is_refused(world, tmp_path, monkeypatch):
    monkeypatch.setattr(limits, "MAX_CAPTURE_PIXELS", 4 * 16 * 12 - 1)
    with pytest.raises(PGCDataError, match="768 pixels together, more than the limit of 767"):
        read_capture(world.capture)


# ---- motions ----------------------------------------------------------------------------------------------
def _npz_declaring(path: Path, shape: tuple[int, ...]) -> Path:
    """An .npz whose 'vertices' header declares ``shape`` (no data follows) and with real faces."""
    with zipfile.ZipFile(path, "w") as zf:
        with zf.open("vertices.npy", "w") as f:
            np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": shape})
        with zf.open("faces.npy", "w") as f:
            np.lib.format.write_array(f, np.array([[0, 1, 2]]))
    return path


@pytest.mark.parametrize("shape,words", [((1_000_000, 8, 3), ["'vertices' frames", "limit of 100000"]),
                                          ((10, 100_000_000, 3), ["'vertices'", "values"])])
def test_a_motion_declaring_huge_arrays_is_refused_from_its_header(shape, words, world, tmp_path, capsys):
    motion = _npz_declaring(tmp_path / "m.npz", shape)
    one_error(["animate", world.asset, "--motion", motion, "--out", tmp_path / "out", "--quiet"],
              ["m.npz", *words], capsys, tmp_path, world.root)


def test_a_motion_folder_of_too_many_frames_is_refused(tmp_path, monkeypatch):
    from pgc.io.motion import load_motion

    for t in range(3):
        (tmp_path / f"f{t}.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    monkeypatch.setattr(limits, "MAX_MOTION_FRAMES", 2)
    with pytest.raises(PGCDataError, match="frames: 3 OBJ frames is more than the limit of 2"):
        load_motion(tmp_path)


# ---- COLMAP models and .ply headers ----------------------------------------------------------------------------
CAMERAS = "1 PINHOLE 16 12 20 20 8 6\n"
IMAGES = "1 1 0 0 0 0 0 3 1 cam.png\n\n"
COLMAP_CASES = {
    "negative_focal": ({"cameras.txt": "1 PINHOLE 16 12 -20 20 8 6\n"}, ["cameras.txt:1", "focal length"]),
    "zero_focal": ({"cameras.txt": "1 SIMPLE_PINHOLE 16 12 0 8 6\n"}, ["cameras.txt:1", "focal length"]),
    "nan_param": ({"cameras.txt": "1 PINHOLE 16 12 20 20 nan 6\n"}, ["cameras.txt:1", "finite"]),
    "inf_focal": ({"cameras.txt": "1 PINHOLE 16 12 inf 20 8 6\n"}, ["cameras.txt:1", "finite"]),
    "zero_width": ({"cameras.txt": "1 PINHOLE 0 12 20 20 8 6\n"}, ["cameras.txt:1", "image size 0x12"]),
    "negative_height": ({"cameras.txt": "1 PINHOLE 16 -12 20 20 8 6\n"}, ["cameras.txt:1", "image size 16x-12"]),
    "huge_size": ({"cameras.txt": "1 PINHOLE 100000 100000 20 20 8 6\n"}, ["cameras.txt:1", "pixels"]),
    "non_utf8_cameras": ({"cameras.txt": b"# \xff\xfe\n" + CAMERAS.encode()}, ["cameras.txt:1", "not UTF-8"]),
    "non_utf8_images": ({"images.txt": b"1 1 0 0 0 0 0 3 1 c\xe9.png\n\n"}, ["images.txt:1", "not UTF-8"]),
    "duplicate_camera": ({"cameras.txt": CAMERAS * 2}, ["cameras.txt:2", "camera id 1 appears twice"]),
    "duplicate_image": ({"images.txt": IMAGES * 2}, ["images.txt:3", "image id 1 appears twice"]),
    "non_unit_quaternion": ({"images.txt": "1 2 0 0 0 0 0 3 1 cam.png\n\n"}, ["images.txt", "norm 2"]),
    "name_outside": ({"images.txt": "1 1 0 0 0 0 0 3 1 ../../etc/cam.png\n\n"}, ["images.txt", "'../../etc/cam.png'"]),
    "name_absolute": ({"images.txt": "1 1 0 0 0 0 0 3 1 /etc/cam.png\n\n"}, ["images.txt", "'/etc/cam.png'"]),
    "keypoints_words": ({"images.txt": "1 1 0 0 0 0 0 3 1 cam.png\na b c\n"}, ["images.txt:2", "numbers"]),
    "bin_huge_count": ({"cameras.txt": None, "cameras.bin": struct.pack("<Q", 2**63)},
                       ["cameras.bin", "number of cameras"]),
    "bin_count_past_end": ({"cameras.txt": None, "cameras.bin": struct.pack("<Q", 1000) + b"\0" * 30},
                           ["cameras.bin", "truncated", "1000 records"]),
    "bin_huge_keypoints": ({"images.txt": None, "images.bin": struct.pack("<Q", 1) + struct.pack(
        "<i7di", 1, 1, 0, 0, 0, 0, 0, 3, 1) + b"cam.png\0" + struct.pack("<Q", 2**40)},
        ["images.bin", "keypoints of image 1"]),
    "bin_negative_focal": ({"cameras.txt": None, "cameras.bin": struct.pack("<Q", 1) + struct.pack(
        "<iiQQ4d", 1, 1, 16, 12, -20.0, 20.0, 8.0, 6.0)}, ["cameras.bin", "camera 1", "focal length"]),
}


@pytest.mark.parametrize("name", list(COLMAP_CASES))
def test_hostile_colmap_models_are_refused_naming_file_and_line(name, tmp_path):
    from pgc.io.colmap import read_colmap_model

    files, words = COLMAP_CASES[name]
    for fname, content in {"cameras.txt": CAMERAS, "images.txt": IMAGES, **files}.items():
        if content is not None:
            p = tmp_path / fname
            p.write_bytes(content) if isinstance(content, bytes) else p.write_text(content)
    with pytest.raises(PGCDataError) as exc:
        read_colmap_model(tmp_path)
    for word in words:
        assert word in str(exc.value), str(exc.value)


def test_a_ply_header_declaring_too_many_gaussians_is_refused(tmp_path):
    from pgc.io.gaussians_ply import read_world_gaussians_ply

    (tmp_path / "g.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99999999999\n"
                                     b"property float x\nend_header\n")
    with pytest.raises(PGCDataError, match=r"g\.ply: header line 'element vertex 99999999999'.*limit"):
        read_world_gaussians_ply(tmp_path / "g.ply")


def test_a_corrupt_label_sidecar_of_a_gltf_mesh_is_a_clear_error(tmp_path):
    pytest.importorskip("trimesh")
    from conftest import seamed_cube
    from pgc.io.mesh import read_mesh, write_mesh

    cube = seamed_cube()
    write_mesh(tmp_path / "m.glb", type(cube)(cube.vertices, cube.faces, face_labels=np.zeros(12, np.int32)))
    (tmp_path / "m.glb.labels.npy").write_bytes(b"\x93NUMPY\x01\x00junk")
    with pytest.raises(PGCDataError, match=r"m\.glb\.labels\.npy: not a readable"):
        read_mesh(tmp_path / "m.glb")


def test_json_nested_too_deeply_for_the_limit_is_refused(tmp_path):
    (tmp_path / "d.json").write_text("[" * (limits.MAX_DEPTH + 1) + "]" * (limits.MAX_DEPTH + 1))
    with pytest.raises(PGCDataError, match=rf"d\.json: lists or objects nested {limits.MAX_DEPTH + 1} levels"):
        limits.read_json(tmp_path / "d.json")
    (tmp_path / "ok.json").write_text("[" * limits.MAX_DEPTH + "]" * limits.MAX_DEPTH)
    assert limits.nesting_depth(limits.read_json(tmp_path / "ok.json")) == limits.MAX_DEPTH


def test_config_errors_from_limits_are_config_errors(tmp_path):
    from pgc.config import load_toml

    (tmp_path / "c.toml").write_text("a = " + "[" * 70 + "]" * 70 + "\n")
    with pytest.raises(PGCConfigError, match="c.toml: lists or objects nested 71 levels"):  # the table is one
        load_toml(tmp_path / "c.toml")


def test_an_implementation_option_that_is_no_integer_names_the_option_and_range():
    from pgc import config

    with pytest.raises(PGCConfigError, match=r"(?s)\[simulator\.xpbd-native\].*option 'substeps': Input should be a "
                                             r"valid integer in \[1, 1000\] \(a float"):
        config.resolve({"simulator": {"use": "xpbd-native", "xpbd-native": {"substeps": 1e30}}},
                       require_available=False, source="run.toml")


# ---- environment maps, output paths, limited readers, rendered frames --------------------------------------------
def test_a_capture_environment_map_with_nan_is_refused_naming_the_map(tmp_path):
    from conftest import make_capture

    capture = make_capture(n_views=2, width=4, height=3)
    write_capture(tmp_path / "cap", capture)
    env = tmp_path / "cap" / "light" / "envmap.exr"
    from pgc.io.images import read_exr, write_exr

    bad = read_exr(env)
    bad[2, 5, 1] = np.inf
    write_exr(env, bad)
    with pytest.raises(PGCDataError, match=rf"{env}: the environment map has 1 non-finite value \(NaN or Inf\) of 96, "
                                           r"first at index \(2, 5, 1\)"):
        read_capture(tmp_path / "cap")
    write_exr(env, bad[:, :5])
    with pytest.raises(PGCDataError, match=rf"{env}: an environment map must be .* H x 2H pixels, got shape \(4, 5, 3\)"):
        read_capture(tmp_path / "cap")


def test_an_os_error_naming_no_file_while_writing_names_the_output(tmp_path):
    from pgc.io.atomic import atomic_path

    (tmp_path / "keep.json").write_text("old")
    with pytest.raises(OSError) as exc:
        with atomic_path(tmp_path / "keep.json"):
            raise OSError(errno.ENOSPC, "No space left on device")  # as write() and fsync() raise it
    assert exc.value.filename == str(tmp_path / "keep.json")
    assert (tmp_path / "keep.json").read_text() == "old" and os.listdir(tmp_path) == ["keep.json"]
    with pytest.raises(OSError) as exc:
        with atomic_path(tmp_path / "keep.json"):
            raise PermissionError(13, "Permission denied", "/elsewhere")
    assert exc.value.filename == "/elsewhere"


@pytest.mark.parametrize("kind", ["fifo", "socket", "dangling"])
def test_eval_refuses_an_out_that_is_no_file_before_measuring(kind, world, tmp_path, capsys, monkeypatch):
    import pgc.pipeline.evaluate as evaluate

    def measured(*a, **k):
        raise AssertionError("the metrics were computed before the --out check")

    monkeypatch.setattr(evaluate, "evaluate_run", measured)
    out = tmp_path / "m.json"
    if kind == "fifo":
        os.mkfifo(out)
    elif kind == "socket":
        sock = socket.socket(socket.AF_UNIX)
        sock.bind(str(out))
    else:
        out.symlink_to(tmp_path / "gone" / "m.json")
    words = {"fifo": "named pipe (FIFO)", "socket": "is a socket", "dangling": "does not exist"}[kind]
    one_error(["eval", world.run, "--gt", world.capture, "--out", out, "--quiet"], [f"--out {out}: ", words],
              capsys, world.root)


def test_an_output_folder_below_a_fifo_is_refused_naming_it(world, tmp_path, capsys):
    os.mkfifo(tmp_path / "pipe")
    one_error(["animate", world.asset, "--motion", world.motion, "--out", tmp_path / "pipe" / "run", "--quiet"],
              ["--out", f"lies below {tmp_path / 'pipe'}", "it is a named pipe (FIFO)"], capsys, tmp_path)


DEEP = "[" * 100_000 + "]" * 100_000


def test_json_and_toml_nested_too_deeply_are_refused_by_every_reader(world, tmp_path, capsys):
    from pgc.bench.records import read_csv
    from pgc.io.limits import read_json

    (tmp_path / "deep.json").write_text(DEEP)
    with pytest.raises(PGCDataError, match=r"deep\.json: lists or objects nested too deeply to parse .*; rerun it"):
        read_json(tmp_path / "deep.json", "bench.json", fix="rerun it")
    (tmp_path / "sweep.toml").write_text("a = " + DEEP + "\n")
    one_error(["sweep", tmp_path / "sweep.toml", "--out", tmp_path / "out"], ["sweep.toml", "nested"], capsys,
              tmp_path)
    assert not (tmp_path / "out").exists()
    run = tmp_path / "run"
    shutil.copytree(world.run, run)
    (run / "render" / "render.json").write_text(DEEP)
    one_error(["eval", run, "--gt", world.capture, "--quiet"], [str(run / "render" / "render.json"), "nested",
                                                                   f"pgc render {run}"], capsys, run)
    (tmp_path / "b.csv").write_text("role,implementation,label,preset,seconds,peak_mb,error_key,failed,detail,"
                                    f"x_reference,settings,versions\nr,i,l,p,1.0,1.0,,,,,\"{'[' * 5000}\",{{}}\n")
    with pytest.raises(PGCDataError, match=r"b\.csv: column 'settings': lists or objects nested too deeply"):
        read_csv(tmp_path / "b.csv")


def test_eval_names_the_frame_file_and_the_array_it_lacks(world, tmp_path, capsys):
    from pgc.pipeline.stage_io import save_npz

    run = tmp_path / "run"
    shutil.copytree(world.run, run)
    full = {k: np.zeros((1, 12, 16, 3), np.float32) for k in ("hybrid", "near", "pbr")}
    full.update({k: np.zeros((1, 12, 16), np.float32) for k in ("alpha", "pbr_alpha")})
    save_npz(run / "render" / "frame_0000.npz", **full)
    frame = run / "render" / "frame_0003.npz"
    save_npz(frame, **{k: v for k, v in full.items() if k != "alpha"})
    one_error(["eval", run, "--gt", world.capture, "--quiet"],
              [f"{frame}: the rendered frame has no array 'alpha'", "pgc render"], capsys, run)
