"""Hostile input through the commands: every malformed file or path is refused with one ``pgc CMD: error:``
line (exit 2) naming the file and the problem, before any heavy work, and leaves existing outputs unchanged.

One tiny capture, asset and run are built once per session (written by the real writers); each case copies
what it corrupts into its own folder.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import struct
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from conftest import install_distribution, make_capture, seamed_cube
from pgc.cli import main
from pgc.errors import PGCDataError
from pgc.io.asset import write_asset
from pgc.io.capture import write_capture
from pgc.io.lock import LOCK_NAME, FolderLock
from pgc.io.mesh import write_mesh
from pgc.pipeline.evaluate import RENDER_INPUTS, render_inputs
from pgc.pipeline.stage_io import save_npz
from pgc.types import GarmentAsset, GaussianSet, Light, Material, Mesh


def tiny_asset(shift: float = 0.0) -> GarmentAsset:
    rng = np.random.default_rng(0)
    garment = seamed_cube()
    n = 12
    gaussians = GaussianSet(parent=rng.integers(0, len(garment.faces), n), means=rng.normal(size=(n, 3)),
                            quats=rng.normal(size=(n, 4)), log_scales=rng.normal(-3, 1, (n, 3)),
                            opacity_logits=rng.normal(size=n), sh=rng.normal(size=(n, 1, 3)))
    body = seamed_cube()
    body = Mesh(body.vertices + shift, body.faces, body.uv, body.face_uv, body.face_labels, name="body")
    return GarmentAsset(garment=garment, body=body, gaussians=gaussians,
                        material=Material("lambertian", {}, rng.random((8, 8, 3)).astype(np.float32)),
                        light=Light(radiance=np.array([1.0, 0.9, 0.8])), config={}, figures={"x": float("nan")})


@dataclass
class World:
    root: Path
    capture: Path
    asset: Path
    run: Path
    motion: Path
    """A valid motion .npz whose frame 0 is the asset's body."""


@pytest.fixture(scope="session")
def world(tmp_path_factory) -> World:
    root = tmp_path_factory.mktemp("hostile_world")
    write_capture(root / "capture", make_capture(n_views=4, width=16, height=12))
    write_asset(root / "asset", tiny_asset())
    body = seamed_cube()
    frames = np.stack([body.vertices + [0, 0.01 * t, 0] for t in range(4)])
    np.savez(root / "motion.npz", vertices=frames, faces=body.faces, fps=30.0)
    run = root / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"asset": str(root / "asset"), "capture": str(root / "capture"),
                                              "motion": "m", "fps": 30.0, "frames": 4, "simulator": "xpbd"}))
    save_npz(run / "garment.npz", vertices=frames, faces=body.faces)
    save_npz(run / "body.npz", vertices=frames, faces=body.faces)
    (run / "render").mkdir()
    (run / "render" / "render.json").write_text(json.dumps({"frames": [0, 3], "cameras": ["cam00"]}))
    for t in (0, 3):
        save_npz(run / "render" / f"frame_{t:04d}.npz", hybrid=np.zeros((1, 12, 16, 3), np.float32))
    (run / "render" / RENDER_INPUTS).write_text(json.dumps(render_inputs(run)))
    return World(root, root / "capture", root / "asset", run, root / "motion.npz")


def snapshot(*folders: Path) -> dict[str, str]:
    """sha256 of every file below ``folders`` (lock files left out: they are the lock's, not outputs)."""
    out = {}
    for folder in folders:
        for p in sorted(folder.rglob("*")):
            if p.is_file() and p.name != LOCK_NAME:
                out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def pgc(argv: list[str], capsys) -> tuple[int, str]:
    capsys.readouterr()
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


# ---- the cases: (id, build(tmp, world) -> (argv, [words the message must hold])) -----------------------------

Build = Callable[[Path, World], tuple[list, list[str]]]
CASES: list[tuple[str, Build]] = []


def case(name: str):
    def deco(fn: Build) -> Build:
        CASES.append((name, fn))
        return fn
    return deco


# config files, through `pgc config validate` and through a run command ------------------------------------
CONFIGS = {
    "non_utf8": (b'[stages.fit_splats]\nlog_every = "\xff\xfe"\n', ["not UTF-8"]),
    "bad_toml": (b"[stages.fit_splats\n", ["not valid TOML"]),
    "unknown_table": (b"[nonsense]\nuse = 'x'\n", ["unknown table [nonsense]"]),
    "unknown_stage": (b"[stages.nope]\n", ["unknown stage [stages.nope]"]),
    "unknown_option": (b"[stages.fit_splats]\nbogus = 1\n", ["bogus"]),
    "inf_float": (b"[stages.fit_splats]\nlr_position = inf\n", ["lr_position", "finite"]),
    "nan_float": (b"[stages.fit_splats]\nlr_position = nan\n", ["lr_position", "finite"]),
    "minus_inf": (b"[stages.material]\nmax_iterations = 3\n[stages.fit_splats]\nlambda_l1 = -inf\n",
                  ["lambda_l1", "finite"]),
    "wrong_type": (b"[stages.fit_splats]\niterations = 'many'\n", ["iterations"]),
    "unknown_impl": (b"[simulator]\nuse = 'no-such-sim'\n", ["no simulator named 'no-such-sim'"]),
    "use_empty": (b"[simulator]\nuse = []\n", ["[simulator] use = []"]),
    "block_not_list": (b"[plugins]\nblock = 'jax'\n", ["block must be a list"]),
    "role_not_table": (b"simulator = 3\n", ["[simulator] must be a table"]),
    "stages_not_table": (b"stages = 3\n", ["[stages] must be a table"]),
    "options_unknown_impl": (b"[simulator]\nuse = 'xpbd-native'\n[simulator.other]\nx = 1\n", ["other"]),
}


def _config_case(kind: str, command: str) -> Build:
    def build(tmp: Path, w: World):
        content, words = CONFIGS[kind]
        cfg = tmp / "bad.toml"
        cfg.write_bytes(content)
        argv = {"validate": ["config", "validate", cfg],
                "reconstruct": ["reconstruct", w.capture, "--out", tmp / "out", "--config", cfg, "--quiet"],
                "render": ["render", w.run, "--config", cfg, "--quiet"]}[command]
        return argv, ["bad.toml", *words]
    return build


for _kind in CONFIGS:
    for _command in ("validate", "reconstruct", "render"):
        if _command == "render" and _kind not in ("non_utf8", "inf_float", "unknown_impl", "block_not_list"):
            continue
        CASES.append((f"config-{_kind}-{_command}", _config_case(_kind, _command)))


@case("config-missing")
def _(tmp, w):
    return ["config", "validate", tmp / "none.toml"], ["none.toml", "not found"]


@case("config-is-folder")
def _(tmp, w):
    return ["config", "show", tmp], [str(tmp), "is a folder"]


@case("config-show-non-utf8")
def _(tmp, w):
    (tmp / "c.toml").write_bytes(b"a = '\xff'\n")
    return ["config", "show", tmp / "c.toml"], ["c.toml", "UTF-8"]


# capture folders (pgc reconstruct) ----------------------------------------------------------------------
def capture_copy(tmp: Path, w: World) -> tuple[Path, dict]:
    cap = tmp / "cap"
    shutil.copytree(w.capture, cap)
    return cap, json.loads((cap / "transforms.json").read_text())


def _capture_case(mutate: Callable[[Path, dict], None], words: list[str]) -> Build:
    def build(tmp: Path, w: World):
        cap, doc = capture_copy(tmp, w)
        mutate(cap, doc)
        if (cap / "transforms.json").exists() and doc is not None:
            if not getattr(mutate, "raw", False):
                (cap / "transforms.json").write_text(json.dumps(doc))
        return ["reconstruct", cap, "--out", tmp / "out", "--quiet"], words
    return build


def raw(fn):
    fn.raw = True
    return fn


def _exr_image(cap: Path, doc: dict, value: float | None) -> None:
    from pgc.io.images import read_image, write_exr

    frame = doc["frames"][1]
    img = read_image(cap / frame["file_path"])
    if value is not None:
        img[2, 3, 1] = value
    write_exr(cap / "images" / "cam01.exr", img)
    frame["file_path"] = "images/cam01.exr"


def _set(path: list, value):
    def mutate(cap: Path, doc: dict):
        target = doc
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return mutate


CAPTURE_CASES = {
    "no_transforms": (raw(lambda c, d: (c / "transforms.json").unlink()), ["transforms.json", "not found"]),
    "malformed_json": (raw(lambda c, d: (c / "transforms.json").write_text("{frames: [")), ["malformed JSON"]),
    "non_utf8_json": (raw(lambda c, d: (c / "transforms.json").write_bytes(b'{"frames": "\xff"}')), ["transforms.json"]),
    "frames_empty": (_set(["frames"], []), ["frames"]),
    "frames_not_list": (_set(["frames"], {"a": 1}), ["frames"]),
    "frame_not_object": (_set(["frames", 0], 7), ["frames[0]"]),
    "missing_image": (raw(lambda c, d: (c / d["frames"][0]["file_path"]).unlink()), ["frames[0]", "not found"]),
    "file_path_number": (_set(["frames", 0, "file_path"], 3), ["frames[0].file_path"]),
    "nan_exr_pixel": (lambda c, d: _exr_image(c, d, float("nan")), ["cam01.exr", "non-finite", "x=3 y=2"]),
    "inf_exr_pixel": (lambda c, d: _exr_image(c, d, float("inf")), ["cam01.exr", "non-finite"]),
    "corrupt_exr": (lambda c, d: (_exr_image(c, d, None), (c / "images" / "cam01.exr").write_bytes(b"v/1\x01junk")),
                    ["cam01.exr", "not a readable OpenEXR"]),
    "corrupt_png": (raw(lambda c, d: (c / d["frames"][0]["file_path"]).write_bytes(b"\x89PNG\r\n\x1a\nxx")),
                    ["cam00.png", "cannot read image"]),
    "truncated_png": (raw(lambda c, d: (c / d["frames"][0]["file_path"]).write_bytes(
        (c / d["frames"][0]["file_path"]).read_bytes()[:60])), ["cam00.png", "truncated"]),
    "size_mismatch": (_set(["frames", 0, "w"], 99), ["frames[0]", "w=99"]),
    "matrix_nan": (_set(["frames", 0, "transform_matrix", 0, 3], float("nan")), ["transform_matrix"]),
    "matrix_shape": (_set(["frames", 0, "transform_matrix"], [[1, 0], [0, 1]]), ["transform_matrix"]),
    "matrix_not_rotation": (_set(["frames", 0, "transform_matrix", 0, 0], 5.0), ["orthonormal"]),
    "matrix_last_row": (_set(["frames", 0, "transform_matrix", 3], [0, 0, 1, 1]), ["last row"]),
    "focal_negative": (_set(["frames", 0, "fl_x"], -10.0), ["focal"]),
    "focal_string": (_set(["frames", 0, "fl_x"], "wide"), ["fl_x"]),
    "duplicate_names": (_set(["frames", 1, "pgc_name"], "cam00"), ["unique"]),
    "name_not_string": (_set(["frames", 1, "pgc_name"], 5), ["pgc_name"]),
    "mask_missing": (raw(lambda c, d: (c / d["frames"][0]["mask_path"]).unlink()), ["mask_path", "not found"]),
    "labels_bad": (_set(["pgc_labels"], {"999": "x"}), ["pgc_labels"]),
    "light_radiance": (_set(["pgc_light", "radiance"], [1, "a", 2]), ["pgc_light.radiance"]),
    "metadata_list": (_set(["pgc_metadata"], [1]), ["pgc_metadata"]),
    "extras_not_object": (_set(["frames", 0, "pgc_extras"], [1]), ["pgc_extras"]),
    "version_unknown": (_set(["pgc_version"], 99), ["pgc_version"]),
}
for _name, (_mutate, _words) in CAPTURE_CASES.items():
    CASES.append((f"capture-{_name}", _capture_case(_mutate, _words)))


@case("capture-not-a-folder")
def _(tmp, w):
    (tmp / "file").write_text("x")
    return ["reconstruct", tmp / "file", "--out", tmp / "out"], ["file"]


# motions (pgc animate --motion FILE) -------------------------------------------------------------------
def _motion_case(make: Callable[[Path], Path], words: list[str]) -> Build:
    def build(tmp: Path, w: World):
        return ["animate", w.asset, "--motion", make(tmp), "--out", tmp / "out", "--quiet"], words
    return build


def npz(**arrays) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        body = seamed_cube()
        data = {"vertices": np.stack([body.vertices] * 3), "faces": body.faces, "fps": 30.0}
        data.update(arrays)
        data = {k: v for k, v in data.items() if v is not None}
        np.savez(tmp / "m.npz", **data)
        return tmp / "m.npz"
    return make


def file_bytes(name: str, content: bytes) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        (tmp / name).write_bytes(content)
        return tmp / name
    return make


def pickled(tmp: Path) -> Path:
    body = seamed_cube()
    np.savez(tmp / "m.npz", vertices=np.array([body.vertices, body.vertices[:3]], dtype=object), faces=body.faces)
    return tmp / "m.npz"


def bad_zip_member(tmp: Path) -> Path:
    with zipfile.ZipFile(tmp / "m.npz", "w") as z:
        z.writestr("vertices.npy", b"\x93NUMPY garbage")
        z.writestr("faces.npy", b"nothing")
    return tmp / "m.npz"


def obj_folder(vertex_counts: list[int]) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        folder = tmp / "frames"
        folder.mkdir()
        cube = seamed_cube()
        for i, n in enumerate(vertex_counts):
            v = cube.vertices if n == 8 else np.vstack([cube.vertices, np.zeros((n - 8, 3))])
            write_mesh(folder / f"frame_{i}.obj", Mesh(v, cube.faces, name="b"))
        return folder
    return make


V = seamed_cube().vertices
MOTION_CASES = {
    "fps_nan": (npz(fps=float("nan")), ["m.npz", "'fps'", "nan"]),
    "fps_zero": (npz(fps=0.0), ["m.npz", "'fps'"]),
    "fps_negative": (npz(fps=-30.0), ["m.npz", "'fps'"]),
    "fps_inf": (npz(fps=float("inf")), ["m.npz", "'fps'"]),
    "fps_huge": (npz(fps=1e9), ["m.npz", "'fps'"]),
    "fps_array": (npz(fps=np.array([30.0, 60.0])), ["m.npz", "'fps'"]),
    "fps_string": (npz(fps=np.array("fast")), ["m.npz", "'fps'"]),
    "pickled": (pickled, ["m.npz", "pickled"]),
    "corrupt_zip": (file_bytes("m.npz", b"PK\x03\x04 not really a zip"), ["m.npz", "not a readable .npz"]),
    "text_as_npz": (file_bytes("m.npz", b"hello"), ["m.npz", "not a readable .npz"]),
    "bad_member": (bad_zip_member, ["m.npz", "not a readable .npz"]),
    "npy_not_npz": (lambda tmp: (np.save(tmp / "m.npy", V), tmp / "m.npy")[1], ["m.npy", ".npz"]),
    "missing_vertices": (npz(vertices=None), ["m.npz", "missing array 'vertices'"]),
    "missing_faces": (npz(faces=None), ["m.npz", "missing array 'faces'"]),
    "vertices_2d": (npz(vertices=V), ["m.npz", "'vertices'"]),
    "vertices_empty": (npz(vertices=np.zeros((0, 8, 3))), ["m.npz", "'vertices'"]),
    "vertices_nan": (npz(vertices=np.stack([V, V + np.nan])), ["m.npz", "non-finite", "frame 1"]),
    "faces_float": (npz(faces=seamed_cube().faces.astype(float)), ["m.npz", "'faces'"]),
    "faces_out_of_range": (npz(faces=seamed_cube().faces + 100), ["m.npz", "out of range"]),
    "faces_empty": (npz(faces=np.zeros((0, 3), int)), ["m.npz", "'faces'"]),
    "body_5m_away": (npz(vertices=np.stack([V + [5.0, 0, 0]] * 3)), ["m.npz", "capture body", "5.0"]),
    "body_scaled": (npz(vertices=np.stack([V * 3.0] * 3)), ["m.npz", "capture body"]),
    "body_in_cm": (npz(vertices=np.stack([V * 100.0] * 3)), ["m.npz", "metres"]),
    "obj_folder_empty": (lambda tmp: ((tmp / "frames").mkdir(), tmp / "frames")[1], ["frames", "no .obj files"]),
    "obj_folder_topology": (obj_folder([8, 9]), ["frame_1.obj", "topology"]),
    "wrong_suffix": (file_bytes("m.txt", b"1 2 3"), ["m.txt", ".npz"]),
    "unknown_builtin": (lambda tmp: Path("no-such-motion"), ["no-such-motion", "built-in"]),
}
for _name, (_make, _words) in MOTION_CASES.items():
    CASES.append((f"motion-{_name}", _motion_case(_make, _words)))


# asset folders (pgc animate ASSET) ----------------------------------------------------------------------
def _asset_case(mutate: Callable[[Path, Path], None], words: list[str]) -> Build:
    def build(tmp: Path, w: World):
        asset = tmp / "asset"
        shutil.copytree(w.asset, asset)
        mutate(asset, tmp)
        return ["animate", asset, "--motion", w.motion, "--out", tmp / "out", "--quiet"], words
    return build


def _manifest(edit: Callable[[dict], None]) -> Callable[[Path, Path], None]:
    def mutate(asset: Path, tmp: Path) -> None:
        m = json.loads((asset / "manifest.json").read_text())
        edit(m)
        (asset / "manifest.json").write_text(json.dumps(m))
    return mutate


def _mixed(asset: Path, tmp: Path) -> None:
    """The new geometry of an interrupted overwrite next to the old manifest."""
    write_asset(tmp / "other", tiny_asset(shift=0.01))
    shutil.copy(tmp / "other" / "gaussians.ply", asset / "gaussians.ply")
    shutil.copy(tmp / "other" / "body.obj", asset / "body.obj")


ASSET_CASES = {
    "no_manifest": (lambda a, t: (a / "manifest.json").unlink(), ["no manifest.json"]),
    "manifest_malformed": (lambda a, t: (a / "manifest.json").write_text("{"), ["manifest.json", "malformed JSON"]),
    "manifest_non_utf8": (lambda a, t: (a / "manifest.json").write_bytes(b'{"a": "\xff"}'), ["manifest.json"]),
    "manifest_list": (lambda a, t: (a / "manifest.json").write_text("[1]"), ["manifest.json", "schema_version"]),
    "schema_unknown": (_manifest(lambda m: m.update(schema_version=7)), ["schema_version 7"]),
    "files_not_object": (_manifest(lambda m: m.update(files=3)), ["'files'"]),
    "no_hashes": (_manifest(lambda m: m.pop("hashes")), ["manifest.json", "hashes"]),
    "garment_edited": (lambda a, t: (a / "garment.obj").write_text((a / "garment.obj").read_text() + "# x\n"),
                       ["garment.obj", "does not match the hash"]),
    "gaussians_missing": (lambda a, t: (a / "gaussians.ply").unlink(), ["gaussians.ply", "not found"]),
    "mixed_files": (_mixed, ["does not match the hash", "two writes"]),
    "material_edited": (lambda a, t: (a / "material.json").write_text('{"brdf": 3}'), ["material.json"]),
    "not_a_folder": (lambda a, t: (shutil.rmtree(a), a.write_text("x")), ["asset"]),
}
for _name, (_mutate, _words) in ASSET_CASES.items():
    CASES.append((f"asset-{_name}", _asset_case(_mutate, _words)))


# run folders (pgc render RUN) ---------------------------------------------------------------------------
def _run_case(mutate: Callable[[Path, World], None], words: list[str], command: str = "render") -> Build:
    def build(tmp: Path, w: World):
        run = tmp / "run"
        shutil.copytree(w.run, run)
        mutate(run, w)
        argv = ["render", run, "--quiet"] if command == "render" else ["eval", run, "--gt", w.capture, "--quiet"]
        return argv, words
    return build


def _run_json(edit: Callable[[dict], None]) -> Callable[[Path, World], None]:
    def mutate(run: Path, w: World) -> None:
        m = json.loads((run / "run.json").read_text())
        edit(m)
        (run / "run.json").write_text(json.dumps(m))
    return mutate


RUN_CASES = {
    "no_run_json": (lambda r, w: (r / "run.json").unlink(), ["run.json", "not found"]),
    "run_json_malformed": (lambda r, w: (r / "run.json").write_text('{"asset": '), ["run.json", "malformed"]),
    "run_json_non_utf8": (lambda r, w: (r / "run.json").write_bytes(b'{"asset": "\xff"}'), ["run.json", "malformed"]),
    "run_json_list": (lambda r, w: (r / "run.json").write_text("[]"), ["run.json", "JSON object"]),
    "asset_missing_field": (_run_json(lambda m: m.pop("asset")), ["run.json", "'asset'"]),
    "frames_string": (_run_json(lambda m: m.update(frames="4")), ["run.json", "'frames'"]),
    "frames_zero": (_run_json(lambda m: m.update(frames=0)), ["run.json", "'frames'"]),
    "fps_string": (_run_json(lambda m: m.update(fps="30")), ["run.json", "'fps'"]),
    "capture_number": (_run_json(lambda m: m.update(capture=3)), ["run.json", "'capture'"]),
    "garment_missing": (lambda r, w: (r / "garment.npz").unlink(), ["garment.npz", "not found"]),
    "body_missing": (lambda r, w: (r / "body.npz").unlink(), ["body.npz", "not found"]),
    "asset_gone": (_run_json(lambda m: m.update(asset="/nonexistent/asset")), ["/nonexistent/asset"]),
    "asset_corrupt": (lambda r, w: (shutil.copytree(w.asset, r.parent / "a2"),
                                    (r.parent / "a2" / "light.json").write_text("{}"),
                                    _run_json(lambda m: m.update(asset=str(r.parent / "a2")))(r, w)),
                      ["light.json", "does not match"]),
}
for _name, (_mutate, _words) in RUN_CASES.items():
    CASES.append((f"run-{_name}", _run_case(_mutate, _words)))


def _render_json(edit: Callable[[dict], None]) -> Callable[[Path, World], None]:
    def mutate(run: Path, w: World) -> None:
        m = json.loads((run / "render" / "render.json").read_text())
        edit(m)
        (run / "render" / "render.json").write_text(json.dumps(m))
    return mutate


def _reanimated(run: Path, w: World) -> None:
    """Another motion simulated into the run after it was rendered."""
    z = dict(np.load(run / "garment.npz"))
    save_npz(run / "garment.npz", vertices=z["vertices"] + 0.1, faces=z["faces"])


RENDER_CASES = {
    "no_render_json": (lambda r, w: (r / "render" / "render.json").unlink(), ["render.json", "pgc render"]),
    "render_json_malformed": (lambda r, w: (r / "render" / "render.json").write_text("{"), ["render.json", "malformed"]),
    "render_json_non_utf8": (lambda r, w: (r / "render" / "render.json").write_bytes(b"\xff\xfe"), ["render.json"]),
    "frames_not_list": (_render_json(lambda m: m.update(frames=3)), ["render.json", "'frames'"]),
    "frames_negative": (_render_json(lambda m: m.update(frames=[-1])), ["render.json", "'frames'"]),
    "cameras_empty": (_render_json(lambda m: m.update(cameras=[])), ["render.json", "'cameras'"]),
    "frame_file_missing": (lambda r, w: (r / "render" / "frame_0003.npz").unlink(), ["frames [3]", "missing"]),
    "stale_after_reanimate": (_reanimated, ["earlier simulation", "pgc render"]),
    "inputs_malformed": (lambda r, w: (r / "render" / RENDER_INPUTS).write_text("{"), [RENDER_INPUTS, "malformed"]),
}
for _name, (_mutate, _words) in RENDER_CASES.items():
    CASES.append((f"render-{_name}", _run_case(_mutate, _words, command="eval")))


# output paths -------------------------------------------------------------------------------------------
def _out_case(command: str, make_out: Callable[[Path], Path], words: list[str]) -> Build:
    def build(tmp: Path, w: World):
        out = make_out(tmp)
        argv = {"reconstruct": ["reconstruct", w.capture, "--out", out, "--quiet"],
                "animate": ["animate", w.asset, "--motion", w.motion, "--out", out, "--quiet"],
                "demo": ["demo", "--preset", "tiny", "--out", out, "--quiet"],
                "synth": ["synth", out, "--preset", "tiny"],
                "eval": ["eval", w.run, "--gt", w.capture, "--out", out, "--quiet"],
                "export": ["export", w.asset, "--format", "obj-seq", "--out", out],
                "sweep": ["sweep", _sweep_case({}, [])(tmp, w)[0][1], "--out", out, "--quiet"]}[command]
        return argv, words
    return build


def _a_file(tmp: Path) -> Path:
    (tmp / "f").write_text("x")
    return tmp / "f"


def _under_file(tmp: Path) -> Path:
    (tmp / "f").write_text("x")
    return tmp / "f" / "sub" / "out"


OUT_KINDS = {"is_file": (_a_file, ["is a file"]), "under_file": (_under_file, ["is a file"])}
for _command in ("reconstruct", "animate", "demo", "synth", "export", "sweep"):
    for _kind, (_make, _words) in OUT_KINDS.items():
        CASES.append((f"out-{_command}-{_kind}", _out_case(_command, _make, _words)))
CASES.append(("out-eval-existing-folder", _out_case("eval", lambda t: t, ["is a folder"])))
CASES.append(("out-eval-under-file", _out_case("eval", lambda t: _under_file(t) / "m.json", ["is a file"])))


@case("out-reconstruct-inside-capture")
def _(tmp, w):
    cap, _ = capture_copy(tmp, w)
    return ["reconstruct", cap, "--out", cap / "asset"], ["inside the capture folder"]


@case("out-animate-inside-asset")
def _(tmp, w):
    asset = tmp / "asset"
    shutil.copytree(w.asset, asset)
    return ["animate", asset, "--motion", w.motion, "--out", asset / "run"], ["inside the asset folder"]


@case("gt-missing")
def _(tmp, w):
    return ["eval", w.run, "--gt", tmp / "nothing", "--quiet"], ["nothing", "not a folder"]


@case("light-missing")
def _(tmp, w):
    run = tmp / "run"
    shutil.copytree(w.run, run)
    return ["render", run, "--light", tmp / "sky.exr", "--quiet"], ["sky.exr", "not found"]


@case("light-corrupt")
def _(tmp, w):
    run = tmp / "run"
    shutil.copytree(w.run, run)
    (tmp / "sky.exr").write_bytes(b"\x76\x2f\x31\x01garbage")
    return ["render", run, "--light", tmp / "sky.exr", "--quiet"], ["sky.exr", "not a readable OpenEXR"]


# the config's [plugins] block is honoured by every run command (core blocked: its metrics are gone) ----------
def _block_case(command: str) -> Build:
    def build(tmp: Path, w: World):
        cfg = tmp / "block.toml"
        cfg.write_text('[plugins]\nblock = ["core"]\n[metric]\nuse = ["psnr"]\n')
        run = tmp / "run"
        shutil.copytree(w.run, run)
        argv = {"reconstruct": ["reconstruct", w.capture, "--out", tmp / "out"],
                "animate": ["animate", w.asset, "--motion", w.motion, "--out", tmp / "out"],
                "render": ["render", run], "eval": ["eval", run, "--gt", w.capture],
                "demo": ["demo", "--preset", "tiny", "--out", tmp / "out"]}[command]
        return [*argv, "--config", cfg, "--quiet"], ["block.toml", "named '", "registered:"]
    return build


for _command in ("reconstruct", "animate", "render", "eval", "demo"):
    CASES.append((f"block-{_command}", _block_case(_command)))


# pgc export and pgc info (an asset or run folder) --------------------------------------------------------------
def _copied_run(tmp: Path, w: World, edit: Callable[[Path], None] | None = None) -> Path:
    run = tmp / "run"
    shutil.copytree(w.run, run)
    if edit is not None:
        edit(run)
    return run


def _source_case(command: str, make: Callable[[Path, World], Path], words: list[str], fmt: str = "obj-seq",
                 out: str = "out") -> Build:
    def build(tmp: Path, w: World):
        source = make(tmp, w)
        extra = ["--format", fmt, "--out", tmp / out] if command == "export" else []
        return [command, source, *extra], words
    return build


def _edited_asset(tmp: Path, w: World) -> Path:
    asset = tmp / "asset"
    shutil.copytree(w.asset, asset)
    (asset / "garment.obj").write_text((asset / "garment.obj").read_text() + "# edited\n")
    return asset


def _npz_edit(name: str, change: Callable[[dict], None]) -> Callable[[Path, World], Path]:
    """A copy of the run whose ``name`` (garment.npz or body.npz) has its arrays changed by ``change``."""
    def make(tmp: Path, w: World) -> Path:
        def edit(run: Path) -> None:
            z = dict(np.load(run / name))
            change(z)
            save_npz(run / name, **z)
        return _copied_run(tmp, w, edit)
    return make


def _file(name: str, content: bytes) -> Callable[[Path, World], Path]:
    return lambda tmp, w: _copied_run(tmp, w, lambda run: (run / name).write_bytes(content))


SOURCE_CASES = {
    "missing": (lambda t, w: t / "nothing", ["nothing", "no such folder"]),
    "neither_asset_nor_run": (lambda t, w: t, ["neither an asset folder", "nor a run folder"]),
    "asset_hash_mismatch": (_edited_asset, ["garment.obj", "does not match the hash"]),
    "run_json_malformed": (_file("run.json", b'{"asset": '), ["run.json", "malformed"]),
    "garment_not_npz": (_file("garment.npz", b"PK\x03\x04 no zip"), ["garment.npz", "not a readable run file"]),
    "garment_nan": (_npz_edit("garment.npz", lambda z: z.update(vertices=z["vertices"] * np.nan)),
                    ["garment.npz", "non-finite"]),
    "body_frames_mismatch": (_npz_edit("body.npz", lambda z: z.update(vertices=z["vertices"][:3])),
                             ["body.npz", "(4, V, 3)"]),
    "body_faces_out_of_range": (_npz_edit("body.npz", lambda z: z.update(faces=np.array([[0, 1, 99]]))),
                                ["body.npz", "'faces'"]),
    "garment_empty": (_file("garment.npz", b""), ["garment.npz", "not a readable run file"]),
    "garment_pickled": (_npz_edit("garment.npz", lambda z: z.update(vertices=np.array([z["vertices"][0], None],
                                                                                       dtype=object))),
                        ["garment.npz", "not a readable run file", "allow_pickle"]),
}
for _name, (_make, _words) in SOURCE_CASES.items():
    for _command in ("export", "info"):
        CASES.append((f"{_command}-{_name}", _source_case(_command, _make, _words)))

EXPORT_CASES = {
    "unknown_format": (lambda t, w: w.asset, ["--format 'fbx'", "unknown export format", "gltf"], "fbx", "out"),
    "gltf_suffix": (lambda t, w: w.asset, ["x.gltf", ".glb"], "gltf", "x.gltf"),
    "usd_suffix": (lambda t, w: w.asset, ["x.obj", ".usd"], "usd", "x.obj"),
    "run_garment_other_asset": (_npz_edit("garment.npz", lambda z: z.update(
        vertices=np.concatenate([z["vertices"], z["vertices"][:, :1]], axis=1))),
                                ["garment.npz", "do not fit the asset's garment"], "obj-seq", "out"),
}
for _name, (_make, _words, _fmt, _out) in EXPORT_CASES.items():
    CASES.append((f"export-{_name}", _source_case("export", _make, _words, _fmt, _out)))


def _export_out(fmt: str, make_out: Callable[[Path], Path], words: list[str]) -> Build:
    def build(tmp: Path, w: World):
        return ["export", w.asset, "--format", fmt, "--out", make_out(tmp)], words
    return build


CASES += [
    ("export-out-under-file", _export_out("gltf", lambda t: _under_file(t).with_suffix(".glb"), ["is a file"])),
    ("export-out-is-folder", _export_out("gltf", lambda t: (t / "d.glb").mkdir() or t / "d.glb",
                                         ["is a folder", "d.glb/garment.glb"])),
]


@case("export-out-inside-asset")
def _(tmp, w):
    asset = tmp / "asset"
    shutil.copytree(w.asset, asset)
    return ["export", asset, "--format", "gltf", "--out", asset / "g.glb"], ["inside the asset folder"]


@case("export-run-out-inside-its-asset")
def _(tmp, w):
    asset = tmp / "asset"
    shutil.copytree(w.asset, asset)
    run = _copied_run(tmp, w, lambda r: _run_json(lambda m: m.update(asset=str(asset)))(r, w))
    return ["export", run, "--format", "obj-seq", "--out", asset / "objs"], ["inside the asset folder"]


def _info_file(name: str, content: bytes, words: list[str]) -> Build:
    def build(tmp: Path, w: World):
        def edit(run: Path) -> None:
            (run / name).parent.mkdir(exist_ok=True)
            (run / name).write_bytes(content)
        return ["info", _copied_run(tmp, w, edit)], words
    return build


CASES += [
    ("info-render-json-malformed", _info_file("render/render.json", b"{", ["render.json", "malformed"])),
    ("info-render-json-list", _info_file("render/render.json", b"[1]", ["render.json", "JSON object"])),
    ("info-metrics-malformed", _info_file("metrics.json", b"{", ["metrics.json", "malformed"])),
    ("info-metrics-non-utf8", _info_file("metrics.json", b'{"a": "\xff"}', ["metrics.json", "malformed"])),
]


# pgc report (a run or demo folder) ---------------------------------------------------------------------------
def _report_case(make: Callable[[Path, World], Path], words: list[str], bench: Callable[[Path], Path] | None = None
                 ) -> Build:
    def build(tmp: Path, w: World):
        return ["report", make(tmp, w), *(["--bench", bench(tmp)] if bench else [])], words
    return build


def _demo(metrics: bytes | None, rendered: bool = True) -> Callable[[Path, World], Path]:
    def make(tmp: Path, w: World) -> Path:
        demo = tmp / "demo"
        (demo / "runs").mkdir(parents=True)
        if rendered:
            shutil.copytree(w.run, demo / "runs" / "m")
        if metrics is not None:
            (demo / "metrics.json").write_bytes(metrics)
        return demo
    return make


def _bench_file(content: bytes) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        (tmp / "bench").mkdir()
        (tmp / "bench" / "bench.json").write_bytes(content)
        return tmp / "bench"
    return make


REPORT_CASES = {
    "not_a_folder": (lambda t, w: t / "nothing", ["nothing", "not a folder"], None),
    "no_run": (lambda t, w: t, ["neither a run folder", "nor a demo folder"], None),
    "demo_nothing_rendered": (_demo(None, rendered=False), ["no rendered runs"], None),
    "run_not_rendered": (lambda t, w: _copied_run(t, w, lambda r: shutil.rmtree(r / "render")),
                         ["no rendered frames", "pgc render"], None),
    "run_json_malformed": (_file("run.json", b"{"), ["run.json", "malformed"], None),
    "run_json_list": (_file("run.json", b"[]"), ["run.json", "JSON object"], None),
    "run_metrics_malformed": (_file("metrics.json", b"{"), ["metrics.json", "malformed"], None),
    "render_json_malformed": (_file("render/render.json", b"{"), ["render.json", "malformed"], None),
    "render_frame_missing": (lambda t, w: _copied_run(t, w, lambda r: (r / "render" / "frame_0003.npz").unlink()),
                             ["frames [3]", "missing"], None),
    "demo_metrics_malformed": (_demo(b"{"), ["metrics.json", "malformed"], None),
    "demo_metrics_list": (_demo(b"[1]"), ["metrics.json", "JSON object"], None),
    "demo_run_json_malformed": (lambda t, w: (_demo(None)(t, w), (t / "demo/runs/m/run.json").write_text("{"))[0],
                                ["run.json", "malformed"], None),
    "bench_missing": (lambda t, w: _copied_run(t, w), ["nothing", "not found", "pgc bench"], lambda t: t / "nothing"),
    "bench_malformed": (lambda t, w: _copied_run(t, w), ["bench.json", "malformed"], _bench_file(b"{")),
    "bench_not_records": (lambda t, w: _copied_run(t, w), ["bench.json", "list of bench records"],
                          _bench_file(b'{"records": 3}')),
    "report_html_is_folder": (lambda t, w: _copied_run(t, w, lambda r: (r / "report.html").mkdir()),
                              ["report.html", "is a folder", "move the folder away"], None),
    "report_folder_is_file": (lambda t, w: _copied_run(t, w, lambda r: (r / "report").write_text("x")),
                              ["report", "is a file", "move the file away"], None),
}
for _name, (_make, _words, _bench) in REPORT_CASES.items():
    CASES.append((f"report-{_name}", _report_case(_make, _words, _bench)))


# pgc sweep (the sweep file and the options) --------------------------------------------------------------------
SWEEP = """[sweep]
name = "t"
steps = ["reconstruct", "animate"]
motions = ["goalpost"]
[scenes.a]
preset = "tiny"
[configurations.c]
[table]
rows = ["configuration"]
"""


def _sweep_case(edits: dict[str, str], words: list[str], options: tuple = (),
                files: dict[str, bytes] | None = None) -> Build:
    """The good sweep file above with each ``old`` text replaced by ``new`` (CAPTURE: the world's capture)."""
    def build(tmp: Path, w: World):
        text = SWEEP
        for old, new in edits.items():
            assert old in text, old
            text = text.replace(old, new.replace("CAPTURE", str(w.capture)))
        (tmp / "s.toml").write_bytes(text.encode("utf-8", "surrogateescape"))
        for name, content in (files or {}).items():
            (tmp / name).write_bytes(content)
        return ["sweep", tmp / "s.toml", "--out", tmp / "out", "--quiet", *options], words
    return build


SWEEP_CASES = {
    "bad_toml": ("[scenes.a]", "[scenes.a", ["s.toml", "not valid TOML"]),
    "non_utf8": ('name = "t"', 'name = "\udcff"', ["s.toml", "not valid TOML"]),
    "unknown_top_key": ("[table]", "[tables]", ["s.toml", "tables: unknown key"]),
    "unknown_sweep_key": ('name = "t"', 'name = "t"\ncolour = "red"', ["s.toml", "[sweep].colour: unknown key"]),
    "unknown_scene_key": ('preset = "tiny"', 'preset = "tiny"\nsize = 3', ["s.toml", "[scenes.a].size"]),
    "name_not_string": ('name = "t"', "name = 3", ["s.toml", "[sweep].name", "3"]),
    "name_a_path": ('name = "t"', 'name = "../elsewhere"', ["s.toml", "[sweep].name", "folder name"]),
    "scene_name_a_path": ("[scenes.a]", '[scenes."a/b"]', ["s.toml", "[scenes.a/b]", "folder name"]),
    "config_not_string": ('name = "t"', 'name = "t"\nconfig = 3', ["s.toml", "[sweep].config"]),
    "config_missing": ('name = "t"', 'name = "t"\nconfig = "nope.toml"', ["s.toml", "nope.toml", "not found"]),
    "base_unknown": ('name = "t"', 'name = "t"\nbase = "huge"', ["s.toml", "[sweep].base", "unknown preset"]),
    "base_not_string": ('name = "t"', 'name = "t"\nbase = ["tiny"]', ["s.toml", "[sweep].base"]),
    "steps_not_list": ('steps = ["reconstruct", "animate"]', 'steps = "reconstruct"', ["s.toml", "[sweep].steps"]),
    "steps_no_prefix": ('steps = ["reconstruct", "animate"]', 'steps = ["animate"]', ["s.toml", "each step needs"]),
    "motions_not_list": ('motions = ["goalpost"]', 'motions = "goalpost"', ["s.toml", "[sweep].motions"]),
    "motion_unknown": ('motions = ["goalpost"]', 'motions = ["moonwalk"]', ["s.toml", "'moonwalk'", "built-in"]),
    "motion_file_corrupt": ('motions = ["goalpost"]', 'motions = ["m.npz"]',
                            ["s.toml", "[sweep].motions", "m.npz", "not a readable .npz"]),
    "seed_nan": ('preset = "tiny"', 'preset = "tiny"\nseed = nan', ["s.toml", "[scenes.a].seed", "nan"]),
    "seed_negative": ('preset = "tiny"', 'preset = "tiny"\nseed = -1', ["s.toml", "[scenes.a].seed"]),
    "seed_float": ('preset = "tiny"', 'preset = "tiny"\nseed = 1.5', ["s.toml", "[scenes.a].seed"]),
    "preset_unknown": ('preset = "tiny"', 'preset = "huge"', ["s.toml", "[scenes.a].preset", "unknown preset"]),
    "capture_missing": ('preset = "tiny"', 'capture = "nowhere"', ["s.toml", "[scenes.a].capture", "nowhere"]),
    "capture_not_string": ('preset = "tiny"', "capture = 3", ["s.toml", "[scenes.a].capture", "string"]),
    "capture_and_synth": ('preset = "tiny"', 'preset = "tiny"\ncapture = "CAPTURE"', ["s.toml", "not both"]),
    "capture_no_ground_truth": ({'"animate"]': '"animate", "render", "eval"]',
                                 "[configurations.c]": '[scenes.b]\ncapture = "CAPTURE"\n[configurations.c]'},
                                ["s.toml", "[scenes.b].capture", "no ground_truth"]),
    "scenes_missing": ('[scenes.a]\npreset = "tiny"\n', "", ["s.toml", "[scenes]", "missing"]),
    "configurations_missing": ("[configurations.c]\n", "", ["s.toml", "[configurations]"]),
    "option_nan": ("[configurations.c]", "[configurations.c.stages.fit_splats]\nlr_position = nan",
                   ["s.toml", "[configurations.c]", "lr_position", "finite"]),
    "option_inf": ("[configurations.c]", "[configurations.c.stages.material]\nlr = inf",
                   ["s.toml", "[configurations.c]", "lr", "finite"]),
    "option_wrong_type": ("[configurations.c]", "[configurations.c.stages.fit_splats]\niterations = 'many'",
                          ["s.toml", "iterations"]),
    "unknown_stage": ("[configurations.c]", "[configurations.c.stages.nostage]", ["s.toml", "unknown stage"]),
    "unknown_implementation": ("[configurations.c]", "[configurations.c.simulator]\nuse = 'nosim'",
                               ["s.toml", "no simulator named 'nosim'"]),
    "table_row_unknown": ('rows = ["configuration"]', 'rows = ["colour"]', ["s.toml", "[table].rows", "'colour'"]),
    "table_where_unknown": ('rows = ["configuration"]', 'where = { colour = "red" }', ["s.toml", "[table].where"]),
}
for _name, _edit in SWEEP_CASES.items():
    _edits = _edit[0] if isinstance(_edit[0], dict) else {_edit[0]: _edit[1]}
    CASES.append((f"sweep-{_name}", _sweep_case(_edits, _edit[-1], files={"m.npz": b"PK\x03\x04 no zip"})))
CASES += [
    ("sweep-file-missing", lambda t, w: (["sweep", t / "none.toml", "--out", t / "out"], ["none.toml", "not found"])),
    ("sweep-retries-negative", _sweep_case({}, ["--retries -1"], ("--retries", "-1"))),
    ("sweep-threads-zero", _sweep_case({}, ["--threads 0"], ("--threads", "0"))),
    ("sweep-scheduler-bogus", _sweep_case({}, ["--scheduler bogus", "local:N"], ("--scheduler", "bogus"))),
    ("sweep-scheduler-zero-workers", _sweep_case({}, ["--scheduler local:0"], ("--scheduler", "local:0"))),
]


@pytest.mark.parametrize("build", [c[1] for c in CASES], ids=[c[0] for c in CASES])
def test_hostile_input_is_one_clear_error_and_changes_nothing(build, world, tmp_path, capsys):
    argv, words = build(tmp_path, world)
    before = snapshot(world.root, tmp_path)
    code, err = pgc(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"pgc {argv[0]}: error: "), err
    assert "Traceback" not in err
    for word in words:
        assert word in err, (word, err)
    assert snapshot(world.root, tmp_path) == before, "a refused command changed files"


@pytest.mark.parametrize("command", ["reconstruct", "animate", "demo", "eval", "export", "sweep", "report"])
def test_a_read_only_output_folder_is_refused_before_any_work(command, world, tmp_path, capsys, monkeypatch):
    """Permissions as the kernel reports them to a non-root user (the tests may run as root, who may write
    anywhere): ``os.access`` says the folder is not writable. ``pgc report`` writes into the run folder."""
    ro = tmp_path / "ro"
    if command == "report":
        shutil.copytree(world.run, ro)
    else:
        ro.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **k: False if Path(p) == ro else real(p, mode, **k))
    out = ro / ("m.json" if command == "eval" else "out")
    argv = ["report", ro] if command == "report" else _out_case(command, lambda t: out, [])(tmp_path, world)[0]
    before = snapshot(world.root, tmp_path)
    code, err = pgc(argv, capsys)
    assert code == 2 and f"{ro} is not writable" in err and err.count("\n") == 1, err
    assert snapshot(world.root, tmp_path) == before


def test_the_suite_covers_every_group_with_enough_cases():
    groups: dict[str, int] = {}
    for name, _ in CASES:
        groups[name.split("-")[0]] = groups.get(name.split("-")[0], 0) + 1
    assert len(CASES) + len(PLY_CASES) + len(COLMAP_CASES) >= 120, groups
    assert {"config", "capture", "motion", "asset", "run", "render", "out", "block", "export", "info", "report",
            "sweep"} <= set(groups)


# .ply files and COLMAP models: the readers' errors (these formats reach the commands through plugins) -----------
def _ply(header: list[str], body: bytes = b"") -> bytes:
    return ("\n".join(["ply", *header, "end_header"]) + "\n").encode() + body


PROPS = [f"property float {p}" for p in ("x", "y", "z", "opacity", "scale_0", "scale_1", "scale_2", "rot_0",
                                         "rot_1", "rot_2", "rot_3", "f_dc_0", "f_dc_1", "f_dc_2")]
ROW = struct.pack("<14f", *([0.0] * 14))
PLY_CASES = {
    "count_word": (_ply(["format binary_little_endian 1.0", "element vertex many", *PROPS]), "not a non-negative"),
    "count_negative": (_ply(["format binary_little_endian 1.0", "element vertex -3", *PROPS]), "not a non-negative"),
    "count_missing": (_ply(["format binary_little_endian 1.0", "element vertex", *PROPS]), "element NAME COUNT"),
    "count_too_large": (_ply(["format binary_little_endian 1.0", "element vertex 5", *PROPS], ROW), "truncated"),
    "no_end_header": (b"ply\nformat ascii 1.0\n", "not a PLY file"),
    "no_magic": (b"hello\nend_header\n", "not a PLY file"),
    "bad_format": (_ply(["format binary_middle_endian 1.0", "element vertex 1", *PROPS], ROW), "unsupported PLY format"),
    "bad_type": (_ply(["format binary_little_endian 1.0", "element vertex 1", "property quad x"]), "unknown PLY property"),
    "property_first": (_ply(["format binary_little_endian 1.0", "property float x"]), "property before any element"),
    "duplicate_property": (_ply(["format binary_little_endian 1.0", "element vertex 1", *PROPS, "property float x"],
                                ROW + b"\0" * 4), "repeats a property"),
    "missing_property": (_ply(["format binary_little_endian 1.0", "element vertex 1", *PROPS[:3]],
                              b"\0" * 12), "missing PLY propert"),
    "nan_property": (_ply(["format binary_little_endian 1.0", "element vertex 1", *PROPS],
                          struct.pack("<14f", np.nan, *([0.0] * 13))), "NaN or Inf"),
    "ascii_bad_rows": (_ply(["format ascii 1.0", "element vertex 2", *PROPS], b"1 2 3\nx y\n"), "ASCII body"),
    "list_property": (_ply(["format binary_little_endian 1.0", "element vertex 1", "property list uchar int idx"]),
                      "list properties"),
    "sh_degree_word": (_ply(["format binary_little_endian 1.0", "comment pgc_sh_degree high", "element vertex 0",
                             *PROPS]), "not a non-negative"),
}


@pytest.mark.parametrize("name", list(PLY_CASES))
def test_hostile_gaussian_ply_is_refused_naming_the_file(name, tmp_path):
    from pgc.io.gaussians_ply import read_world_gaussians_ply

    content, words = PLY_CASES[name]
    (tmp_path / "g.ply").write_bytes(content)
    with pytest.raises(PGCDataError) as exc:
        read_world_gaussians_ply(tmp_path / "g.ply")
    assert str(tmp_path / "g.ply") in str(exc.value) and words in str(exc.value)


CAMERAS = "1 PINHOLE 16 12 20 20 8 6\n"
IMAGE = "1 {q} 0 0 3 1 cam.png\n\n"
COLMAP_CASES = {
    "zero_quaternion": ({"images.txt": IMAGE.format(q="0 0 0 0")}, ["images.txt", "no rotation"]),
    "nan_quaternion": ({"images.txt": IMAGE.format(q="nan 0 0 0")}, ["images.txt", "no rotation"]),
    "nan_translation": ({"images.txt": "1 1 0 0 0 nan 0 3 1 cam.png\n\n"}, ["images.txt", "translation"]),
    "short_line": ({"images.txt": "1 1 0 0\n\n"}, ["images.txt:1", "IMAGE_ID"]),
    "unknown_model": ({"cameras.txt": "1 FISHEYE9 16 12 1\n"}, ["cameras.txt:1", "unknown camera model"]),
    "param_count": ({"cameras.txt": "1 PINHOLE 16 12 20\n"}, ["cameras.txt:1", "parameters"]),
    "missing_camera": ({"images.txt": "1 1 0 0 0 0 0 3 9 cam.png\n\n"}, ["references camera 9"]),
    "no_images": ({"images.txt": ""}, ["no registered images"]),
    "no_images_file": ({"images.txt": None}, ["no images.bin or images.txt"]),
    "truncated_bin": ({"cameras.txt": None, "cameras.bin": b"\x01\x00\x00\x00\x00\x00\x00\x00\x01"},
                      ["cameras.bin", "truncated"]),
}


@pytest.mark.parametrize("name", list(COLMAP_CASES))
def test_hostile_colmap_model_is_refused_naming_the_file(name, tmp_path):
    from pgc.io.colmap import read_colmap_model

    files, words = COLMAP_CASES[name]
    model = {"cameras.txt": CAMERAS, "images.txt": IMAGE.format(q="1 0 0 0"), **files}
    for fname, content in model.items():
        if content is not None:
            p = tmp_path / fname
            p.write_bytes(content) if isinstance(content, bytes) else p.write_text(content)
    with pytest.raises(PGCDataError) as exc:
        read_colmap_model(tmp_path)
    for word in words:
        assert word in str(exc.value), str(exc.value)


# plugins that misbehave on import, locks, unexpected errors, strict JSON, metrics ------------------------------
@pytest.fixture
def exiting_plugin(tmp_path, monkeypatch):
    """An installed distribution whose plugin calls sys.exit on import, and one that raises."""
    return install_distribution(tmp_path / "site", monkeypatch, "hostile-plugins",
                                {"hostile_exit": "import sys\nsys.exit(3)\n",
                                 "hostile_raise": "raise RuntimeError('needs libbar.so')\n"},
                                {"hostileexit": "hostile_exit", "hostileraise": "hostile_raise"})


def test_a_plugin_exiting_on_import_is_reported_not_fatal(exiting_plugin, capsys):
    capsys.readouterr()
    code = main(["plugins"])
    out = capsys.readouterr().out
    assert code == 0 and "simulator:" in out
    assert "hostileexit (hostile-plugins): plugin failed to load: SystemExit: 3" in out
    assert "hostileraise (hostile-plugins): plugin failed to load: RuntimeError: needs libbar.so" in out
    main(["plugins", "--json"])
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out) if r["role"] is None}
    assert rows["hostileexit"]["reason"] == "plugin failed to load: SystemExit: 3"


def test_a_blocked_plugin_is_not_even_imported(exiting_plugin, tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[plugins]\nblock = ["hostileexit", "hostileraise"]\n')
    from pgc.commands._common import discover

    class Args:
        config = str(cfg)

    names = {b.plugin for b in discover(Args()).broken}
    assert not names & {"hostileexit", "hostileraise"}, names

    class NoConfig:
        config = None

    assert {"hostileexit", "hostileraise"} <= {b.plugin for b in discover(NoConfig()).broken}


def test_a_second_writer_fails_at_once_naming_the_holder(world, tmp_path, capsys):
    out = tmp_path / "out"
    with FolderLock(out, "pgc reconstruct"):
        code, err = pgc(["reconstruct", world.capture, "--out", out, "--quiet"], capsys)
    assert code == 2 and f"pid {os.getpid()} (pgc reconstruct, since" in err and str(out) in err
    run = tmp_path / "run"
    shutil.copytree(world.run, run)
    for argv in (["render", run], ["eval", run, "--gt", world.capture]):
        with FolderLock(run, "pgc animate"):
            code, err = pgc([*argv, "--quiet"], capsys)
        assert code == 2 and "being written by" in err and "pgc animate" in err, err


def test_the_lock_is_released_when_its_holder_is_killed(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from pgc.io.lock import FolderLock\n"
                               f"with FolderLock({str(out)!r}, 'holder'):\n print('held', flush=True); time.sleep(60)"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        from pgc.errors import PGCLockError

        with pytest.raises(PGCLockError, match=f"pid {holder.pid} \\(holder"):
            FolderLock(out, "second").acquire()
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    time.sleep(0.05)
    with FolderLock(out, "third"):
        pass


def test_an_unexpected_exception_is_one_line_exit_1_and_debug_shows_the_traceback(world, tmp_path, capsys,
                                                                                    monkeypatch):
    import pgc.pipeline.evaluate as evaluate

    def boom(*a, **k):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(evaluate, "evaluate_run", boom)
    run = tmp_path / "run"
    shutil.copytree(world.run, run)
    code, err = pgc(["eval", run, "--gt", world.capture, "--quiet"], capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert "unexpected ZeroDivisionError: division by zero" in err and "--debug" in err
    code, err = pgc(["--debug", "eval", run, "--gt", world.capture, "--quiet"], capsys)
    assert code == 1 and "Traceback (most recent call last)" in err and "ZeroDivisionError" in err


def test_os_errors_are_user_errors_with_the_path(world, tmp_path, capsys, monkeypatch):
    import pgc.pipeline.evaluate as evaluate

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied", str(tmp_path / "x.json"))

    monkeypatch.setattr(evaluate, "evaluate_run", denied)
    run = tmp_path / "run"
    shutil.copytree(world.run, run)
    code, err = pgc(["eval", run, "--gt", world.capture, "--quiet"], capsys)
    assert code == 2 and err.strip() == (f"pgc eval: error: {tmp_path / 'x.json'}: Permission denied; check the "
                                         "permissions, or give a folder you can write")


def test_every_json_written_is_strict(world):
    manifest = (world.asset / "manifest.json").read_text()
    assert json.loads(manifest, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    assert json.loads(manifest)["figures"] == {"x": None}


@pytest.mark.parametrize("metric", ["psnr", "ssim", "fsim"])
def test_metrics_agree_that_an_empty_mask_has_nothing_to_measure(metric):
    from pgc.metrics.fsim import fsim
    from pgc.metrics.psnr import psnr
    from pgc.metrics.ssim import ssim

    fn = {"psnr": psnr, "ssim": ssim, "fsim": fsim}[metric]
    rng = np.random.default_rng(0)
    a, b = rng.random((32, 32, 3)), rng.random((32, 32, 3))
    with pytest.raises(PGCDataError, match=f"{metric}: the mask is empty"):
        fn(a, b, np.zeros((32, 32)))
    assert np.isfinite(fn(a, b, np.ones((32, 32))))
