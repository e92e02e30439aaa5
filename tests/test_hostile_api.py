"""Hostile input at the API and messages that must point the right way.

Numeric APIs (splat renderers, the fused kernel, metrics, filters, BRDFs, the simulator's time step) refuse
NaN/Inf with a :class:`PGCDataError` naming the array and the count, and metrics refuse images smaller than their
window; commands name the file or address at fault (an environment map with NaN, a full disk, an unreachable
Dask scheduler); a plugin raising KeyboardInterrupt on import is a broken plugin while a real Ctrl-C still ends
the command with 130.
"""

from __future__ import annotations

import errno
import importlib
import json
import re
import shutil
import signal
import sys

import numpy as np
import pytest

from conftest import install_distribution, seamed_cube, tilted_camera
from pgc.cli import main, os_error_message
from pgc.errors import PGCDataError
from pgc.registry import default_registry
from pgc.roles.splat_renderer import RenderOutput, SplatRenderer
from pgc.types import BodyMotion, WorldGaussians
from test_hostile import _sweep_case, pgc, snapshot, world  # noqa: F401  (world: the session fixture)

FIELDS = ("means", "quats", "scales", "opacities", "sh")


def gaussians(**bad: np.ndarray) -> WorldGaussians:
    n = 3
    arrays = dict(means=np.array([[0.0, 0.0, 2.0], [0.05, 0.0, 2.0], [0.0, 0.05, 2.0]]),
                  quats=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), scales=np.full((n, 3), 0.05),
                  opacities=np.full(n, 0.9), sh=np.full((n, 1, 3), 0.5))
    return WorldGaussians(**{**arrays, **bad})


def poisoned(field: str, value: float = np.nan) -> WorldGaussians:
    good = gaussians()
    a = np.array(getattr(good, field), dtype=np.float64)
    a.flat[1] = value
    return gaussians(**{field: a})


def _renderers() -> list[str]:
    names = ["reference"] + [i.name for i in default_registry().list("splat_renderer") if i.available]
    return names


def _render(name: str, world: WorldGaussians, background=None) -> RenderOutput:
    camera = tilted_camera(16, 12, 20.0)
    if name == "reference":
        from pgc.splats.reference import render_reference

        return render_reference(world, camera, background)
    return default_registry().create("splat_renderer", name).render(world, camera, background)


# ---- splat renderers: one check at the role's entry ----------------------------------------------------------
@pytest.mark.parametrize("renderer", _renderers())
@pytest.mark.parametrize("field", FIELDS)
def test_every_splat_renderer_refuses_a_nan_naming_the_array_and_count(renderer, field):
    with pytest.raises(PGCDataError, match=rf"WorldGaussians\.{field} has 1 non-finite value \(NaN or Inf\)"):
        _render(renderer, poisoned(field))


@pytest.mark.parametrize("renderer", _renderers())
def test_splat_renderers_refuse_inf_a_nan_background_and_wrong_shapes(renderer):
    with pytest.raises(PGCDataError, match=r"WorldGaussians\.scales has 1 non-finite"):
        _render(renderer, poisoned("scales", np.inf))
    with pytest.raises(PGCDataError, match="background has 1 non-finite"):
        _render(renderer, gaussians(), np.array([0.0, np.nan, 0.0]))
    with pytest.raises(PGCDataError, match=r"WorldGaussians\.opacities must have shape \(N\) with N = 3"):
        _render(renderer, gaussians(opacities=np.full(2, 0.9)))
    assert np.isfinite(_render(renderer, gaussians()).color).all()


def test_a_third_party_splat_renderer_gets_the_check_before_its_own_code():
    calls = []

    class Recording(SplatRenderer):
        def render(self, gaussians, camera, background=None, sh_degree=None):
            calls.append(sh_degree)
            return RenderOutput(np.zeros((camera.height, camera.width, 3), np.float32),
                                np.zeros((camera.height, camera.width), np.float32))

        def fit(self, capture, mesh, settings=None, reporter=None):
            raise NotImplementedError

    with pytest.raises(PGCDataError, match=r"Recording\.render: WorldGaussians\.sh has 1 non-finite"):
        Recording().render(poisoned("sh"), tilted_camera(16, 12, 20.0))
    assert calls == []
    Recording().render(gaussians(), tilted_camera(16, 12, 20.0), None, 0)
    assert calls == [0]


def test_the_fused_kernel_refuses_nan_unless_its_caller_checked():
    from pgc.splats import fused
    from pgc.splats.quaternion import quat_to_rotmat

    if not fused.available():
        pytest.skip("the fused kernel does not build here")
    g, camera = poisoned("means"), tilted_camera(16, 12, 20.0)
    arrays = [np.asarray(x, np.float32) for x in (g.means, quat_to_rotmat(g.quats), g.scales, g.opacities, g.sh)]
    args = (fused.camera_vector(camera, 0.01), np.zeros((12, 16, 3), np.float32), 12, 16, 1)
    with pytest.raises(PGCDataError, match=r"fused splat kernel: means has 1 non-finite value .* index \(0, 1\)"):
        fused.forward(arrays, *args)
    out = fused.forward(arrays, *args, check_finite=False)  # the kernel drops it: what the check exists for
    assert np.isfinite(out.color).all()


# ---- metrics -------------------------------------------------------------------------------------------------
def _metric_fns():
    from pgc.metrics import fsim, psnr, ssim

    return {"psnr": psnr, "ssim": ssim, "fsim": fsim}


@pytest.mark.parametrize("metric", ["psnr", "ssim", "fsim"])
def test_metrics_refuse_non_finite_input_naming_the_argument(metric):
    fn = _metric_fns()[metric]
    rng = np.random.default_rng(0)
    a = rng.random((16, 16, 3)).astype(np.float32)
    b = a.copy()
    b[2, 3, 1] = np.nan
    with pytest.raises(PGCDataError, match=rf"{metric}: pred has 1 non-finite value .* index \(2, 3, 1\)"):
        fn(b, a)
    with pytest.raises(PGCDataError, match=rf"{metric}: target has 1 non-finite"):
        fn(a, np.where(np.isnan(b), np.inf, b))  # inf would be clipped by the sRGB encoding and scored
    mask = np.ones((16, 16))
    mask[0, 0] = np.nan
    with pytest.raises(PGCDataError, match=rf"{metric}: mask has 1 non-finite"):
        fn(a, a, mask)
    with pytest.raises(PGCDataError, match=rf"{metric}: pred shape \(16, 16, 3\) != target shape \(16, 15, 3\)"):
        fn(a, a[:, :15])
    assert np.isfinite(fn(a, np.clip(a + 0.1, 0, 1)))


@pytest.mark.parametrize("metric,size,minimum", [("ssim", 10, 11), ("fsim", 5, 6), ("fsim", 1, 6), ("psnr", 0, 1)])
def test_metrics_refuse_images_smaller_than_their_window_stating_the_minimum(metric, size, minimum):
    fn = _metric_fns()[metric]
    a = np.full((size, size, 3), 0.5, np.float32)
    with pytest.raises(PGCDataError, match=rf"{metric}: images of {size}x{size} px are too small: at least "
                                           rf"{minimum}x{minimum} px"):
        fn(a, a * 0.5)
    b = np.full((minimum, minimum, 3), 0.5, np.float32)
    assert np.isfinite(fn(b, b * 0.5))


@pytest.mark.parametrize("name", ["psnr", "ssim", "fsim"])
def test_metric_role_implementations_refuse_nan(name):
    metric = default_registry().create("metric", name)
    a = np.full((16, 16, 3), 0.5, np.float32)
    with pytest.raises(PGCDataError, match=f"{name}: target has 768 non-finite"):
        metric(a, np.full_like(a, np.nan))


# ---- filters, BRDFs, the simulator ---------------------------------------------------------------------------
BUILTIN_FILTERS = [n for n in ("torch", "jax", "opencv", "box")
                   if any(i.name == n and i.available for i in default_registry().list("filter"))]


@pytest.mark.parametrize("name", BUILTIN_FILTERS)
def test_filters_refuse_nan_naming_the_array_and_count(name):
    filt = default_registry().create("filter", name)
    image = np.full((8, 8, 3), 0.5, np.float32)
    image[2, 2, 0] = np.nan
    with pytest.raises(PGCDataError, match=r"filter: image has 1 non-finite value .* index \(2, 2, 0\)"):
        filt.lowpass(image, np.ones((8, 8)), 3)
    alpha = np.ones((8, 8))
    alpha[1, 1] = alpha[4, 4] = np.inf
    with pytest.raises(PGCDataError, match=r"filter: alpha has 2 non-finite values"):
        filt.highpass(np.full((8, 8, 3), 0.5), alpha, 3)


@pytest.mark.parametrize("name", ["lambertian", "disney", "pgc-sheen"])
def test_brdfs_refuse_nan_directions_colours_and_parameters(name):
    brdf = default_registry().create("brdf", name)
    wi, wo, colour = np.array([[0.0, 0.0, 1.0]] * 2), np.array([[0.0, 0.6, 0.8]] * 2), np.full((2, 3), 0.5)
    params = brdf.initial_params()
    assert np.isfinite(brdf.eval_cos(wi, wo, colour, params)).all()
    for arg in range(3):
        args = [wi.copy(), wo.copy(), colour.copy()]
        args[arg][1, 0] = np.nan
        with pytest.raises(PGCDataError, match=rf"brdf '{name}': {['wi', 'wo', 'base_color'][arg]} has 1 non-finite"):
            brdf.eval_cos(*args, params)
    for key in params:
        bad = {**params, key: float("nan")}
        with pytest.raises(PGCDataError, match=rf"brdf '{name}': parameter '{key}' has 1 non-finite"):
            brdf.eval_cos(wi, wo, colour, bad)


def test_a_simulator_refuses_a_nan_frame_rate_instead_of_reporting_divergence():
    impl = next(i for i in default_registry().list("simulator") if i.available)
    sim = impl.create({})
    body = seamed_cube()
    motion = BodyMotion(np.stack([body.vertices * 1.3] * 2), body.faces, fps=30.0)
    motion.fps = float("nan")  # set after construction, which refuses it (below)
    with pytest.raises(PGCDataError, match="fps must be a finite positive number .* got nan"):
        sim.simulate(body, motion)


@pytest.mark.parametrize("fps", [float("nan"), float("inf"), 0.0, -30.0])
def test_a_body_motion_refuses_a_frame_rate_that_is_no_finite_positive_number(fps):
    body = seamed_cube()
    with pytest.raises(PGCDataError, match=r"motion 'm': fps must be a finite positive number \(frames per second\)"):
        BodyMotion(np.stack([body.vertices] * 2), body.faces, fps=fps, name="m")


@pytest.mark.parametrize("width,ok", [(16, True), (16.0, True), (np.int64(16), True), (15.5, False),
                                      (float("nan"), False), (True, False), ("16", False)])
def test_a_camera_refuses_a_size_that_is_no_whole_number_instead_of_truncating_it(width, ok):
    from pgc.types import Camera

    def make():
        return Camera(np.diag([20.0, 20.0, 1.0]), np.eye(3), np.zeros(3), width, 12, name="c")

    if ok:
        assert make().width == 16 and isinstance(make().width, int)
        return
    with pytest.raises(PGCDataError, match=r"camera 'c': width must be a whole number of pixels, got "):
        make()


# ---- the metric, filter and pbr_renderer roles check inputs before any implementation --------------------------
def test_a_third_party_metric_gets_the_checks_before_its_own_code():
    from pgc.roles.metric import Metric

    calls = []

    class Windowed(Metric):
        def min_image_size(self, masked):
            return 8, "its 8 px window"

        def compute(self, pred, target, mask):
            calls.append(pred.shape)
            return float(np.mean(np.abs(pred - target)))

    a = np.full((8, 8, 3), 0.5, np.float32)
    bad = a.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(PGCDataError, match=r"metric Windowed: pred has 1 non-finite value .* index \(1, 2, 0\)"):
        Windowed()(bad, a)
    with pytest.raises(PGCDataError, match=r"metric Windowed: target has 1 non-finite"):
        Windowed()(a, np.where(np.isnan(bad), np.inf, bad))
    with pytest.raises(PGCDataError, match=r"metric Windowed: images of 7x7 px are too small: at least 8x8 px are "
                                           r"needed \(its 8 px window\)"):
        Windowed()(a[:7, :7], a[:7, :7])
    with pytest.raises(PGCDataError, match=r"metric Windowed: images must be \(H, W, 3\)"):
        Windowed()(a[..., 0], a[..., 0])
    assert calls == []
    assert Windowed()(a, a * 0.5) == pytest.approx(0.25) and calls == [(8, 8, 3)]


def _lpips():
    if not any(i.name == "lpips" and i.available for i in default_registry().list("metric")):
        pytest.skip("lpips is unavailable here")
    try:
        return {net: default_registry().create("metric", "lpips", {"net": net}) for net in ("alex", "vgg")}
    except Exception as exc:  # noqa: BLE001  (weights not converted on this machine)
        pytest.skip(f"lpips cannot be built: {exc}")


@pytest.mark.parametrize("net,minimum", [("alex", 32), ("vgg", 16)])
def test_lpips_refuses_nan_and_images_smaller_than_its_backbone(net, minimum):
    lpips = _lpips()[net]
    rng = np.random.default_rng(0)
    a = rng.random((minimum, minimum, 3)).astype(np.float32)
    b = a.copy()
    b[0, 1, 2] = np.nan
    with pytest.raises(PGCDataError, match=r"lpips: pred has 1 non-finite value .* index \(0, 1, 2\)"):
        lpips(b, a)
    small = a[:minimum - 1, :minimum - 1]
    with pytest.raises(PGCDataError, match=rf"lpips: images of {minimum - 1}x{minimum - 1} px are too small: at "
                                           rf"least {minimum}x{minimum} px are needed \(the '{net}' backbone"):
        lpips(small, small * 0.5)
    assert np.isfinite(lpips(a, a * 0.5))
    assert np.isfinite(lpips(small, small * 0.5, np.ones(small.shape[:2], np.float32)))  # a mask pads the crop


def test_a_third_party_filter_gets_the_checks_before_its_own_code():
    from pgc.roles.filter import Filter

    calls = []

    class Recording(Filter):
        def lowpass(self, image, alpha, kernel_size):
            calls.append((image.dtype, kernel_size))
            return image

    image = np.full((6, 6, 3), 0.5)
    image[3, 4, 1] = np.inf
    with pytest.raises(PGCDataError, match=r"filter: image has 1 non-finite value .* index \(3, 4, 1\)"):
        Recording().lowpass(image, np.ones((6, 6)), 3)
    with pytest.raises(PGCDataError, match="kernel_size must be a positive odd integer"):
        Recording().highpass(np.zeros((6, 6, 3)), np.ones((6, 6)), 4)
    assert calls == []
    Recording().lowpass(np.zeros((6, 6, 3)), np.ones((6, 6)), 3.0)
    assert calls == [(np.float32, 3)]


def _pbr_case(where: str):
    from pgc.types import Light, Material

    material = Material("lambertian", {"base_color": [0.5, 0.5, 0.5]}, np.full((8, 8, 3), 0.5, np.float32))
    light = Light(np.ones(3), envmap=np.full((4, 8, 3), 0.5, np.float32))
    if where == "material.base_color":
        material.base_color[2, 3, 1] = np.nan
    elif where == "material.params['base_color']":
        material.params["base_color"] = [0.5, float("nan"), 0.5]
    elif where == "light.radiance":
        light.radiance = np.array([1.0, np.inf, 1.0])
    elif where == "light.envmap":
        light.envmap[0, 0, 0] = np.nan
    return material, light


PBR_INPUTS = ["material.base_color", "material.params['base_color']", "light.radiance", "light.envmap"]


@pytest.mark.parametrize("where", PBR_INPUTS)
def test_the_torch_pbr_renderer_refuses_nan_textures_lights_and_parameters(where):
    if not any(i.name == "torch" and i.available for i in default_registry().list("pbr_renderer")):
        pytest.skip("the torch pbr_renderer is unavailable here")
    renderer = default_registry().create("pbr_renderer", "torch", {"directions": 8})
    mesh, camera = seamed_cube(), tilted_camera(8, 6, 10.0)
    material, light = _pbr_case(where)
    with pytest.raises(PGCDataError, match=rf"pbr_renderer TorchPBRRenderer\.render: {re.escape(where)} has 1 "
                                           "non-finite value"):
        renderer.render(mesh, material, light, camera)
    with pytest.raises(PGCDataError, match=rf"TorchPBRRenderer\.render_texture: {re.escape(where)} has 1 non-finite"):
        renderer.render_texture(mesh, material, light, camera, (8, 8))
    good_material, good_light = _pbr_case("")
    assert np.isfinite(renderer.render(mesh, good_material, good_light, camera).color).all()


def test_a_third_party_pbr_renderer_gets_the_check_before_its_own_code():
    from pgc.roles.pbr_renderer import PBRRenderer

    calls = []

    class Recording(PBRRenderer):
        def render(self, mesh, material, light, camera, occluder=None):
            calls.append("render")

        def render_texture(self, mesh, material, light, camera, resolution, occluder=None):
            calls.append("texture")

    for where in PBR_INPUTS:
        material, light = _pbr_case(where)
        with pytest.raises(PGCDataError, match=rf"Recording\.render: {re.escape(where)} has 1 non-finite"):
            Recording().render(None, material, light, None)
        with pytest.raises(PGCDataError, match=rf"Recording\.render_texture: {re.escape(where)} has 1 non-finite"):
            Recording().render_texture(None, material=material, light=light, camera=None, resolution=(4, 4))
    assert calls == []
    Recording().render(None, *_pbr_case(""), None)
    assert calls == ["render"]


@pytest.mark.parametrize("kind", ["shape", "nan"])
def test_the_mitsuba_emitter_names_one_problem_of_an_environment_map(kind):
    pytest.importorskip("mitsuba")
    from pgc.types import Light
    from pgc_mitsuba.scene import emitter_dict

    env = np.full((4, 8, 3), 0.5, np.float32)
    if kind == "shape":
        env = env[:, :7]
    else:
        env[1, 1] = np.nan
    words = {"shape": r"light\.envmap must be an \(H, 2H, 3\) lat-long map, got shape \(4, 7, 3\)$",
             "nan": r"light\.envmap has 3 non-finite values \(NaN or Inf\) of 96, first at index \(1, 1, 0\)"}[kind]
    with pytest.raises(PGCDataError, match=words) as exc:
        emitter_dict(Light(np.ones(3), envmap=env))
    assert ("non-finite" in str(exc.value)) == (kind == "nan")


# ---- messages that name the file, the path or the address ------------------------------------------------------
@pytest.mark.parametrize("kind", ["nan", "shape", "negative"])
def test_a_bad_environment_map_is_named_with_its_problem(kind, world, tmp_path, capsys):  # noqa: F811
    from pgc.io.images import write_exr

    run = tmp_path / "run"
    shutil.copytree(world.run, run)
    env = np.full((4, 8, 3), 0.5, np.float32)
    if kind == "nan":
        env[1, 2] = np.nan
    elif kind == "shape":
        env = env[:, :5]
    else:
        env[0, 0, 0] = -1.0
    write_exr(tmp_path / "sky.exr", env)
    words = {"nan": "has 3 non-finite values (NaN or Inf) of 96, first at index (1, 2, 0)",
             "shape": "H x 2H pixels, got shape (4, 5, 3)", "negative": "1 negative radiance values"}[kind]
    before = snapshot(world.root, run)
    code, err = pgc(["render", run, "--light", tmp_path / "sky.exr", "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and err.startswith("pgc render: error: "), err
    assert f"{tmp_path / 'sky.exr'}: " in err and words in err, err
    assert snapshot(world.root, run) == before


def test_a_full_disk_names_the_folder_being_written(world, tmp_path, capsys, monkeypatch):  # noqa: F811
    import pgc.pipeline.evaluate as evaluate

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")  # as write() raises it: no file name

    monkeypatch.setattr(evaluate, "evaluate_run", full)
    run = tmp_path / "run"
    shutil.copytree(world.run, run)
    code, err = pgc(["eval", run, "--gt", world.capture, "--quiet"], capsys)
    assert code == 2 and err.strip() == (f"pgc eval: error: {run}: No space left on device; the disk is full: free "
                                         "space on it or write to another disk"), err


def test_a_full_disk_during_export_names_the_output(world, tmp_path, capsys, monkeypatch):  # noqa: F811
    import pgc.io.export as export

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(export, "export", full)
    out = tmp_path / "g.glb"
    code, err = pgc(["export", world.asset, "--format", "gltf", "--out", out], capsys)
    assert code == 2 and f"error: {out}: No space left on device; the disk is full" in err, err


def test_os_errors_without_a_path_do_not_pretend_to_have_one():
    message = os_error_message(OSError(errno.EIO, "Input/output error"))
    assert message == "Input/output error; the disk reported an I/O error: check it, or write to another disk"
    assert os_error_message(PermissionError(13, "Permission denied", "/x")).startswith("/x: Permission denied")


def test_an_unreachable_scheduler_is_named_with_how_to_start_one(world, tmp_path, capsys):  # noqa: F811
    import dask
    import distributed  # noqa: F401  its defaults loaded first: leaving set() would drop them all otherwise

    argv, _ = _sweep_case({}, [], ("--scheduler", "tcp://127.0.0.1:1"))(tmp_path, world)
    with dask.config.set({"distributed.comm.timeouts.connect": "0.5s"}):
        code, err = pgc(argv, capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert "pgc sweep: error: --scheduler tcp://127.0.0.1:1: no Dask scheduler could be reached at " \
           "tcp://127.0.0.1:1" in err, err
    assert "dask scheduler --port" in err and "--scheduler local:N" in err and "the disk" not in err


# ---- plugins: KeyboardInterrupt raised by a plugin against a real Ctrl-C --------------------------------------
@pytest.fixture
def interrupting_plugins(tmp_path, monkeypatch):
    """Installed plugins that raise KeyboardInterrupt: on import, and in their registration hook."""
    site = install_distribution(
        tmp_path / "site", monkeypatch, "hostile-kbi",
        {"hostile_kbi": "raise KeyboardInterrupt('plugin asks to stop')\n",
         "hostile_kbi_hook": "from pgc.registry import hookimpl\n\n@hookimpl\n"
                             "def pgc_register_implementations():\n    raise KeyboardInterrupt\n"},
        {"hostilekbi": "hostile_kbi", "hostilekbihook": "hostile_kbi_hook"})
    yield site
    for name in ("hostile_kbi", "hostile_kbi_hook"):
        sys.modules.pop(name, None)


def test_a_plugin_raising_keyboard_interrupt_is_a_broken_plugin(interrupting_plugins, capsys):
    capsys.readouterr()
    code = main(["plugins"])
    out = capsys.readouterr().out
    assert code == 0 and "simulator:" in out, out
    assert "hostilekbi (hostile-kbi): plugin failed to load: KeyboardInterrupt: plugin asks to stop" in out
    assert "hostilekbihook (hostile-kbi): plugin failed to load: KeyboardInterrupt" in out
    main(["plugins", "--json"])
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out) if r["role"] is None}
    assert rows["hostilekbi"]["reason"] == "plugin failed to load: KeyboardInterrupt: plugin asks to stop"


def test_a_real_ctrl_c_during_a_plugin_import_still_ends_the_command(interrupting_plugins, capsys):
    (interrupting_plugins / "hostile_kbi.py").write_text(
        "import os, signal\nos.kill(os.getpid(), signal.SIGINT)\nIMPORTED = True\n")
    importlib.invalidate_caches()
    capsys.readouterr()
    assert main(["plugins"]) == 130
    assert "pgc plugins: interrupted" in capsys.readouterr().err
    from pgc.registry import Registry

    sys.modules.pop("hostile_kbi")  # imported (the signal was the user's): import it again
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # whatever an earlier test left there
    try:
        with pytest.raises(KeyboardInterrupt):  # outside the command line too: Python's own handler, raised after
            Registry.discover()
    finally:
        signal.signal(signal.SIGINT, previous)
