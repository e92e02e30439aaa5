"""The material fit's differentiable renders, split into shards whose gradients are summed in a fixed order.

Dr.Jit accumulates the gradient of a scene-wide parameter by atomic adds from all its threads, in a racy
order: a render's gradient on more than one thread differs from run to run. So every shard renders on ONE
Dr.Jit thread, and the cores are used by rendering the shards in separate processes at once: each film's
views are dealt round-robin into ``shards`` sub-films, shard 0 renders in this process and the others in
spawned worker processes, and the losses and gradients are added in shard order. The same shards run one
after the other in this process when the allotment is one core, with the same bytes as a result.

Values cross the process boundary as float64 numpy arrays: the optimised parameters in, the loss and the
gradient of every parameter out. The light's RGB radiance sets the emitter: a constant's radiance, or an
environment map's pixels as the map of unit radiance times the RGB radiance (a differentiable expression, so
``prb`` returns its gradient from its own adjoint pass, decorrelated from the primal image: multiplying the
rendered image by the radiance instead gives a gradient biased by the image's Monte Carlo variance: docs/pbr.md).
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from pgc.types import Camera, Light, Material, Mesh
from pgc_mitsuba.runtime import mitsuba
from pgc_mitsuba.scene import scene_dict
from pgc_mitsuba.sensors import pinhole_sensor


RESIDUAL_SAMPLER = "ldsampler"
"""Mitsuba's sampler of :meth:`ShardScene.residual` (low discrepancy, as the synthetic captures: at 64 spp its
residuals' noise on the fit's pixels was a tenth of the ``independent`` sampler's)."""


@dataclass
class ShardFilm:
    """One shard's part of a film: views of one image size tiled left to right."""

    cameras: list[Camera]
    target: np.ndarray
    """(H, W x views, 3) float32 linear target."""
    weight: np.ndarray
    """(H, W x views) float32 pixel weights."""
    count: float
    """Normaliser of the loss: 3 x the weight sum of the WHOLE film (all shards), so shard losses add up."""


@dataclass
class SceneSpec:
    """What builds the fit's Mitsuba scene (picklable: sent to the worker processes)."""

    garment: Mesh
    occluder: Mesh | None
    material: Material
    integrator: dict[str, Any]
    occluder_albedo: float
    smooth_normals: bool
    keys: list[str]
    """Scene parameters whose values are set and whose gradients are returned, in order (the radiance follows
    them in the values and gradients)."""
    spp: int
    light: Light
    """The light's shape: a constant or an environment map (with its rotation) at unit radiance."""


class ShardScene:
    """A Mitsuba scene with a set of shard films; renders one with given parameter values (those of
    ``spec.keys``, then the RGB radiance), returns the loss (the weighted squared error over ``count``) and the
    gradient of every value."""

    def __init__(self, spec: SceneSpec, films: list[ShardFilm]):
        mi = mitsuba()
        self.spec = spec
        self.scene = mi.load_dict(scene_dict(spec.garment, spec.material, spec.light, spec.integrator,
                                             spec.occluder, spec.occluder_albedo, spec.smooth_normals))
        self.params = mi.traverse(self.scene)
        self.kinds = {key: type(self.params[key]) for key in spec.keys}
        self.unit_envmap = mi.TensorXf(self.params["light.data"]) if spec.light.envmap is not None else None
        self.films = [(pinhole_sensor(f.cameras, spec.spp), mi.TensorXf(f.target), mi.TensorXf(f.weight[..., None]),
                       f.count) for f in films]
        self.cameras = [f.cameras for f in films]
        self.residual_sensors: dict[tuple[int, int], Any] = {}

    def _set(self, values: list[np.ndarray], grad: bool) -> Any:
        """Set the scene's values (those of ``spec.keys``, then the RGB radiance), tracking their gradients
        when ``grad``; returns the radiance variable."""
        mi = mitsuba()
        import drjit as dr

        *scene_values, radiance = values
        for key, value in zip(self.spec.keys, scene_values):
            variable = self.kinds[key](*[float(x) for x in np.asarray(value).reshape(-1)])
            dr.make_opaque(variable)  # a literal would be baked into the kernel: a new compilation every step
            self.params[key] = variable
            if grad:
                dr.enable_grad(self.params[key])
        rgb = [float(x) for x in np.asarray(radiance).reshape(3)]
        gain = mi.Color3f(*rgb) if self.unit_envmap is None else mi.TensorXf(np.asarray(rgb, np.float32),
                                                                             shape=(1, 1, 3))
        dr.make_opaque(gain)
        if grad:
            dr.enable_grad(gain)
        if self.unit_envmap is None:
            self.params["light.radiance.value"] = gain
        else:
            self.params["light.data"] = self.unit_envmap * gain
        self.params.update()
        return gain

    def render(self, film: int, values: list[np.ndarray], seed: int, seed_grad: int) -> tuple[float, list[np.ndarray]]:
        """The loss of shard film ``film`` at ``values`` and its gradient (``spec.spp`` samples per pixel)."""
        mi = mitsuba()
        import drjit as dr

        gain = self._set(values, grad=True)
        sensor, target, weight, count = self.films[film]
        img = mi.render(self.scene, self.params, sensor=sensor, spp=self.spec.spp, seed=seed, seed_grad=seed_grad)
        loss = dr.sum(weight * dr.square(img[:, :, :3] - target), axis=None) / count
        dr.backward(loss)
        grads = [np.asarray(dr.grad(self.params[key]), dtype=np.float64).reshape(-1) for key in self.spec.keys]
        return float(loss.array[0]), [*grads, np.asarray(dr.grad(gain), dtype=np.float64).reshape(-1)]

    def residual(self, film: int, values: list[np.ndarray], spp: int, seed: int) -> np.ndarray:
        """The weighted residuals ``sqrt(weight / count) (render - target)`` of shard film ``film`` at
        ``values``, flattened (float64; their squares sum to the shard's loss), from a render at ``spp``
        samples per pixel of :data:`RESIDUAL_SAMPLER` with ``seed``, without gradients."""
        mi = mitsuba()
        import drjit as dr

        self._set(values, grad=False)
        _, target, weight, count = self.films[film]
        if (film, spp) not in self.residual_sensors:
            self.residual_sensors[film, spp] = pinhole_sensor(self.cameras[film], spp, RESIDUAL_SAMPLER)
        img = mi.render(self.scene, sensor=self.residual_sensors[film, spp], spp=spp, seed=seed)
        return np.asarray(dr.sqrt(weight / count) * (img[:, :, :3] - target), dtype=np.float64).reshape(-1)


def split_film(cameras: list[Camera], targets: list[np.ndarray], weights: list[np.ndarray],
               shards: int) -> list[ShardFilm]:
    """Deal one film's views round-robin into at most ``shards`` sub-films (fewer when it has fewer views)."""
    count = 3.0 * sum(float(w.sum()) for w in weights)
    parts = [list(range(s, len(cameras), shards)) for s in range(min(shards, len(cameras)))]
    return [ShardFilm([cameras[i] for i in p], np.concatenate([targets[i] for i in p], axis=1),
                      np.concatenate([weights[i] for i in p], axis=1), count) for p in parts]


def serve(inbox: Connection, outbox: Connection) -> None:
    """Worker process: build the scene from the first message (spec, films; None for films owned elsewhere),
    then answer requests (method, film, arguments) for :meth:`ShardScene.render` or :meth:`ShardScene.residual`
    until the pipe closes or None arrives."""
    mitsuba()
    import drjit as dr

    dr.set_thread_count(1)
    spec, films = inbox.recv()
    index = {i: k for k, i in enumerate(i for i, f in enumerate(films) if f is not None)}
    scene = ShardScene(spec, [f for f in films if f is not None])
    while True:
        try:
            request = inbox.recv()
        except EOFError:
            return
        if request is None:
            return
        method, film, arguments = request
        try:
            outbox.send(("ok", getattr(scene, method)(index[film], *arguments)))
        except Exception as exc:  # noqa: BLE001 - reported to the parent, which raises it
            outbox.send(("error", f"{type(exc).__name__}: {exc}"))


class Worker:
    """A worker process (``python -m pgc_mitsuba.shards``) and its two pipes. Started as a new program, not a
    multiprocessing child, so the caller's ``__main__`` is never re-imported; in its own session, so Ctrl-C at
    the terminal reaches only the parent, whose exit closes the pipes and so ends the worker."""

    def __init__(self, spec: SceneSpec, films: list[ShardFilm | None]):
        from_parent, to_child = os.pipe()
        from_child, to_parent = os.pipe()
        self.process = subprocess.Popen([sys.executable, "-m", "pgc_mitsuba.shards", str(from_parent),
                                         str(to_parent)], pass_fds=(from_parent, to_parent),
                                        stdin=subprocess.DEVNULL, start_new_session=True)
        os.close(from_parent)
        os.close(to_parent)
        self.outbox = Connection(to_child, readable=False)
        self.inbox = Connection(from_child, writable=False)
        self.outbox.send((spec, films))

    def send(self, request: Any) -> None:
        self.outbox.send(request)

    def recv(self) -> Any:
        try:
            return self.inbox.recv()
        except EOFError:
            raise RuntimeError(f"material fit worker exited with code {self.process.wait()}") from None

    def close(self) -> None:
        try:
            self.outbox.send(None)
        except OSError:
            pass
        self.outbox.close()
        self.inbox.close()
        try:
            self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


class ShardPool:
    """Renders every shard of a film and sums losses and gradients in shard order. ``films[f]`` holds film
    f's shards. With ``processes`` > 1, shards 1.. render in ``processes - 1`` worker processes (shard s on
    worker (s - 1) mod workers) while shard 0 renders here; else all render here, one after the other."""

    def __init__(self, spec: SceneSpec, films: list[list[ShardFilm]], processes: int):
        self.films = films
        shards = max(len(parts) for parts in films)
        workers = max(0, min(processes, shards) - 1)
        self.owner = {s: None if workers == 0 or s == 0 else (s - 1) % workers for s in range(shards)}
        # every (film, shard) has a flat index; each scene holds the films of the shards it owns
        flat = [(f, s) for f, parts in enumerate(films) for s in range(len(parts))]
        self.flat_index = {key: k for k, key in enumerate(flat)}
        here = [key for key in flat if self.owner[key[1]] is None]
        self.local_index = {key: k for k, key in enumerate(here)}
        self.workers = [Worker(spec, [films[f][s] if self.owner[s] == w else None for f, s in flat])
                        for w in range(workers)]
        self.scene = ShardScene(spec, [films[f][s] for f, s in here])

    def render(self, film: int, values: list[np.ndarray], seed: int, seed_grad: int) -> tuple[float, list[np.ndarray]]:
        """Loss and gradients of ``film`` (all its shards) at ``values``; shard s uses the seeds + s."""
        parts = range(len(self.films[film]))
        for s in parts:
            if self.owner[s] is not None:
                self.workers[self.owner[s]].send(("render", self.flat_index[film, s], (values, seed + s,
                                                                                       seed_grad + s)))
        results: dict[int, tuple[float, list[np.ndarray]]] = {}
        for s in parts:
            if self.owner[s] is None:
                results[s] = self.scene.render(self.local_index[film, s], values, seed + s, seed_grad + s)
        for s in parts:
            if self.owner[s] is not None:
                results[s] = self._reply(s)
        loss = sum(results[s][0] for s in parts)
        grads = [sum(results[s][1][k] for s in parts) for k in range(len(values))]
        return float(loss), grads

    def residual(self, values: list[np.ndarray], spp: int, seed: int) -> np.ndarray:
        """The weighted residuals of every film and shard at ``values`` (:meth:`ShardScene.residual`; shard s
        uses ``seed + s``), concatenated in (film, shard) order: their squares sum to the films' summed loss."""
        order = [(f, s) for f, parts in enumerate(self.films) for s in range(len(parts))]
        for f, s in order:
            if self.owner[s] is not None:
                self.workers[self.owner[s]].send(("residual", self.flat_index[f, s], (values, spp, seed + s)))
        results = {(f, s): self.scene.residual(self.local_index[f, s], values, spp, seed + s)
                   for f, s in order if self.owner[s] is None}
        for f, s in order:
            if self.owner[s] is not None:
                results[f, s] = self._reply(s)
        return np.concatenate([results[key] for key in order])

    def _reply(self, shard: int) -> Any:
        """The next answer of the worker that owns ``shard``; a worker's error is raised here."""
        status, payload = self.workers[self.owner[shard]].recv()
        if status != "ok":
            raise RuntimeError(f"material fit worker: {payload}")
        return payload

    def close(self) -> None:
        for worker in self.workers:
            worker.close()
        self.workers = []

    def __enter__(self) -> "ShardPool":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


if __name__ == "__main__":
    serve(Connection(int(sys.argv[1]), writable=False), Connection(int(sys.argv[2]), readable=False))
