"""The independent ground truth of ``pgc eval --mode independent``: the truth garment simulated on its own.

In ``appearance`` mode (the default) the truth garment is carried along the reconstructed garment's own
simulation (:mod:`pgc.pipeline.transfer`), so appearance is judged on matching geometry. In ``independent``
mode nothing of the pipeline's simulation is used, as in the paper's evaluation:

- rest garment: the capture's garment made again by the synthetic generator (:func:`pgc.synth.garments.make_garment`,
  the capture's garment kind, fit and looseness) at ``truth_resolution`` times finer edges than the capture's;
- simulator: eval setting ``truth_simulator`` (default ``newton-vbd``, Vertex Block Descent in Newton) with that
  implementation's own defaults (over which ``truth_options`` may set some): its cloth parameters, not the
  pipeline's (docs/simulation.md, "Independent truth");
- body: :func:`truth_body_motion`, the true body driven by the run's motion, while the run's garment moves on the
  body the run chose (:mod:`pgc.pipeline.motion_source`: the true one, or the one fitted to the capture);
- appearance: the capture's truth garment (its textures, fibres, detail) tied to the fine rest garment and carried
  along the fine simulation; nothing is aligned to the pipeline's garment.

The simulation is cached under ``RUN/gt/truth_sim/<key>.npz``, keyed on everything it depends on.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pgc.errors import PGCConfigError, PGCDataError, PGCPluginError
from pgc.events import Reporter
from pgc.stages.eval import MODES
from pgc.types import BodyMotion, Mesh

TRUTH_SIM_VERSION = "1"
"""Bumped when the truth simulation's inputs or maths change (part of its cache key)."""


def check_mode(mode: str) -> str:
    """``mode`` once it is one of :data:`MODES`; else one clear error."""
    if mode not in MODES:
        raise PGCConfigError(f"eval mode '{mode}' is unknown; use one of: {', '.join(MODES)} (pgc eval --mode)")
    return mode


def truth_body_motion(run_dir: Path, capture_dir: Path, pose_body: Callable[[], Any] | None = None) -> BodyMotion:
    """The body the truth garment moves on: the capture's true body driven by the run's motion, the one place
    that decides it.

    The run's clip or built-in motion (run.json ``motion_source``) is made again on the true body's rig, whichever
    body the run moved on (``body``: its true body or the body fitted to the capture), and must give the run's
    frames. A run on a motion file of body vertices (or one recorded before runs named their motion source) moved
    on those vertices, which must be the true body's (same vertex count). ``pose_body`` makes the configured body
    model, which an AMASS pose clip needs for its skeleton."""
    from pgc.pipeline.animate import read_run
    from pgc.pipeline.motion_source import MotionSource, capture_body, resolve_motion
    from pgc.synth.ground_truth import read_body_model

    meta = read_run(run_dir)
    fps, frames = float(meta.get("fps", 30.0)), int(np.load(run_dir / "body.npz")["vertices"].shape[0])
    record = meta.get("motion_source")
    if record is not None and record.get("kind") != "file":
        source = MotionSource.from_record(record, str(run_dir / "run.json"))
        motion = resolve_motion(source, lambda what: capture_body(capture_dir, None, what), pose_body)
        if motion.num_frames != frames or abs(motion.fps - fps) > 1e-6:
            raise PGCDataError(f"{run_dir}: its motion '{source.spec}' on the capture's true body gives "
                               f"{motion.num_frames} frames at {motion.fps:g} fps, the run has {frames} at {fps:g}; "
                               "animate the run again")
        return BodyMotion(motion.vertices, motion.faces, fps=motion.fps, name="truth")
    z = np.load(run_dir / "body.npz")
    true_body = read_body_model(capture_dir)
    if z["vertices"].shape[1] != len(true_body.vertices):
        raise PGCDataError(f"{run_dir / 'body.npz'}: the run moved on a motion file of {z['vertices'].shape[1]} body "
                           f"vertices, the capture's true body has {len(true_body.vertices)}; independent evaluation "
                           "needs the true body driven by the run's motion: animate the run with a clip or a built-in "
                           "motion, or with a motion file of the true body")
    return BodyMotion(z["vertices"], z["faces"], fps=fps, name="truth")


def truth_rest_garment(capture_dir: Path, factor: float) -> Mesh:
    """The capture's truth garment from the generator with edges ``factor`` times shorter than the capture's."""
    from pgc.synth.garments import make_garment
    from pgc.synth.ground_truth import read_body_model, read_ground_truth

    manifest = read_ground_truth(capture_dir).manifest or {}
    preset = manifest.get("preset")
    if not isinstance(preset, dict) or not {"garment_edge", "garment", "fit", "looseness"} <= set(preset):
        raise PGCDataError(f"{capture_dir}/ground_truth/scene.json: no 'preset' with garment_edge, garment, fit and "
                           "looseness (written by an older 'pgc synth'); generate the capture again")
    return make_garment(read_body_model(capture_dir), preset["garment"], looseness=float(preset["looseness"]),
                        resolution=float(preset["garment_edge"]) / factor, fit=preset["fit"])


def truth_simulator(name: str, registry: Any = None) -> Any:
    """The registered simulator ``name`` (an :class:`pgc.registry.Implementation`), once available."""
    from pgc.registry import Registry

    registry = registry or Registry.discover()
    impl = registry.get("simulator", name)
    if not impl.available:
        raise PGCPluginError(f"independent evaluation simulates the truth with simulator '{name}', which is "
                             f"unavailable: {impl.reason}; or choose another with [stages.eval] truth_simulator")
    return impl


def truth_simulation(run_dir: Path, capture_dir: Path, settings: Any, registry: Any = None,
                     reporter: Reporter | None = None, pose_body: Callable[[], Any] | None = None,
                     ) -> tuple[np.ndarray, Mesh, dict[str, Any]]:
    """The fine truth garment simulated on the true body (:func:`truth_body_motion`, with ``pose_body``): vertices
    (T, V, 3) per motion frame, its rest mesh and the simulator's figures; cached under ``RUN/gt/truth_sim``."""
    import time

    from pgc.io.atomic import atomic_open, write_json
    from pgc.pipeline.cache import array_key, content_key, file_key

    impl = truth_simulator(settings.truth_simulator, registry)
    options = impl.validate_options(settings.truth_options, where="[stages.eval] truth_options")
    motion = truth_body_motion(run_dir, capture_dir, pose_body)
    gt_dir = capture_dir / "ground_truth"
    key = content_key("truth-sim", TRUTH_SIM_VERSION, file_key(gt_dir / "scene.json"),
                      file_key(gt_dir / "body_model.npz"), array_key(motion.vertices), motion.fps,
                      settings.truth_resolution, impl.name, impl.version,
                      None if options is None else options.model_dump(mode="json"))
    folder = run_dir / "gt" / "truth_sim"
    path, meta = folder / f"{key}.npz", folder / f"{key}.json"
    if path.is_file() and meta.is_file():
        z = np.load(path)
        return z["vertices"], Mesh(z["rest"], z["faces"], name="truth"), json.loads(meta.read_text())
    start = time.perf_counter()
    rest = truth_rest_garment(capture_dir, settings.truth_resolution)
    build = time.perf_counter() - start
    sim = impl.create(options).simulate(rest, motion, reporter)
    figures = {"simulator": impl.name, "options": None if options is None else options.model_dump(mode="json"),
               "resolution_factor": settings.truth_resolution, "rest_vertices": len(rest.vertices),
               "rest_build_seconds": build, "seconds": sim.figures.get("seconds"),
               "max_penetration_fraction": sim.figures.get("max_penetration_fraction")}
    folder.mkdir(parents=True, exist_ok=True)
    with atomic_open(path, "wb") as f:
        np.savez(f, vertices=sim.vertices, rest=rest.vertices, faces=rest.faces)
    write_json(meta, figures)
    return sim.vertices, rest, figures


def independent_garment(gt_garment: Mesh, run_dir: Path, capture_dir: Path, frames: list[int], settings: Any,
                        registry: Any = None, reporter: Reporter | None = None,
                        pose_body: Callable[[], Any] | None = None) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The capture's truth garment carried along the fine truth simulation at ``frames`` (F, V, 3), the true body
    there (F, B, 3) and the simulation's figures (``pose_body``: see :func:`truth_body_motion`)."""
    from pgc.pipeline.transfer import embed, place

    vertices, rest, figures = truth_simulation(run_dir, capture_dir, settings, registry, reporter, pose_body)
    if max(frames) >= len(vertices):
        raise PGCDataError(f"{run_dir}: rendered frames {frames} lie beyond the truth simulation's {len(vertices)}")
    embedding = embed(gt_garment.vertices, rest)
    garment = np.stack([place(embedding, rest, vertices[t]) for t in frames])
    return garment, truth_body_motion(run_dir, capture_dir, pose_body).vertices[frames], figures
