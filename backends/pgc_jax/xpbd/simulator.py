"""``xpbd-jax``: :func:`pgc.sim.xpbd.advance_frame` jitted whole (substeps and iterations become
``lax.fori_loop``); compiled once per garment shape (and per self-collision pair bucket): the scalar settings
(substeps, iterations, time step, damping, offset, friction, ...) are traced, not compiled in."""

from __future__ import annotations

import contextlib
from dataclasses import fields

import jax
import jax.numpy as jnp
import numpy as np

from pgc.arrays import ArrayOps, array_ops
from pgc.sim.driver import Stepper, XPBDSimulator
from pgc.sim.xpbd import FrameInput, Statics, StepSettings, advance_frame
from pgc.sim.model import ClothModel
from pgc.sim.options import XPBDOptions

JAX = array_ops("jax")


def _advance(ops: ArrayOps, self_collision: bool, scalars: dict, statics: Statics, x: jax.Array, v: jax.Array,
             frame: FrameInput) -> tuple:
    """:func:`advance_frame` with every setting but ``self_collision`` (a Python branch) a traced scalar."""
    return advance_frame(ops, StepSettings(self_collision=self_collision, **scalars), statics, x, v, frame)


_FRAME = jax.jit(_advance, static_argnums=(0, 1))
"""One compiled program per (array shapes, self-collision), shared by every stepper and setting."""
_SCALARS = tuple(f.name for f in fields(StepSettings) if f.name != "self_collision")


class JaxStepper(Stepper):
    def __init__(self, model: ClothModel, settings: StepSettings, options: XPBDOptions) -> None:
        super().__init__(model, settings, options)
        self.f64 = options.dtype == "float64"
        self.dtype = np.float64 if self.f64 else np.float32
        free = (model.inv_mass > 0).astype(np.float64)
        with self._precision():
            self.statics = Statics(self._j(model.inv_mass), self._j(free),
                                   tuple(tuple(self._j(a) for a in g) for g in self.groups),
                                   self._j(np.array(options.gravity)))

    def _precision(self) -> contextlib.AbstractContextManager:
        """float64 runs enable x64 only around this stepper's calls (JAX's flag is process-wide)."""
        return jax.enable_x64(True) if self.f64 else contextlib.nullcontext()

    def _j(self, a: np.ndarray) -> jax.Array:
        a = np.asarray(a)
        if a.dtype.kind in "iu":
            return jnp.asarray(a.astype(np.int32))
        if a.dtype == bool:
            return jnp.asarray(a)
        return jnp.asarray(a.astype(self.dtype))

    def set_state(self, x: np.ndarray, v: np.ndarray) -> None:
        with self._precision():
            self.x, self.v = self._j(x), self._j(v)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.x, np.float64), np.asarray(self.v, np.float64)

    def advance(self, frame: FrameInput) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        with self._precision():
            inputs = FrameInput(*(self._j(a) for a in frame))
            scalars = {name: getattr(self.settings, name) for name in _SCALARS}
            self.x, self.v, res = _FRAME(JAX, self.settings.self_collision, scalars, self.statics, self.x, self.v,
                                         inputs)
            res = jax.device_get(res)
            x = np.asarray(self.x, dtype=np.float64)
        return (x, self.in_model_order([np.asarray(g[0], np.float64) for g in res]),
                self.in_model_order([np.asarray(g[1], np.float64) for g in res]))


class JaxXPBDSimulator(XPBDSimulator):
    """XPBD cloth in JAX (one jitted XLA program per frame)."""

    def make_stepper(self, model: ClothModel, settings: StepSettings) -> Stepper:
        return JaxStepper(model, settings, self.options)
