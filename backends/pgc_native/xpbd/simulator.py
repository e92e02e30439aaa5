"""``xpbd-native``: :func:`pgc.sim.xpbd.advance_frame` as one call of the compiled kernel ``xpbd.cpp``.

The kernel follows the array maths element by element (same formulas, same order of the region tests,
same argmin tie rule), in float32 or float64. Parallel loops run over vertices, or over the constraints of
one graph colour (which share no vertex); the Jacobi sweep gathers each vertex's corrections in a fixed
order: the bytes of the result do not depend on the thread count.
"""

from __future__ import annotations

import ctypes

import numpy as np

from pgc.cores import ThreadChooser
from pgc.sim.driver import Stepper, XPBDSimulator
from pgc.sim.xpbd import FrameInput, StepSettings
from pgc.sim.model import ClothModel
from pgc_native.specs_xpbd import NativeXPBDOptions
from pgc_native.xpbd import library


def _ptr(a: np.ndarray) -> int:
    return a.ctypes.data


class NativeStepper(Stepper):
    """Positions and velocities in the kernel's precision; the static arrays prepared once per model."""

    options: NativeXPBDOptions

    def __init__(self, model: ClothModel, settings: StepSettings, options: NativeXPBDOptions) -> None:
        super().__init__(model, settings, options)
        lib = library.load()
        self.dtype = np.float64 if options.dtype == "float64" else np.float32
        self.fn = lib.pgc_xpbd_frame_f64 if options.dtype == "float64" else lib.pgc_xpbd_frame_f32
        f = self._f
        cat = [np.concatenate([g[k] for g in self.groups]) for k in range(5)]
        self.ci, self.cj = cat[0].astype(np.int32), cat[1].astype(np.int32)
        self.rest, self.alpha_t, self.share = f(cat[2]), f(cat[3]), f(cat[4])
        self.group_start = np.concatenate([[0], np.cumsum([len(g[0]) for g in self.groups])]).astype(np.int64)
        self.inv_mass, self.free = f(model.inv_mass), f((model.inv_mass > 0).astype(np.float64))
        self.gravity = f(np.array(options.gravity, dtype=np.float64))
        self.jacobi = options.solver == "jacobi"
        # Jacobi gather per vertex: its i-side corrections by constraint, then its j-side ones (code 2c + side)
        ends = np.concatenate([self.ci, self.cj]).astype(np.int64)
        codes = np.concatenate([2 * np.arange(len(self.ci)), 2 * np.arange(len(self.ci)) + 1])
        self.inc = codes[np.argsort(ends, kind="stable")].astype(np.int32)
        counts = np.bincount(ends, minlength=model.num_vertices)
        self.inc_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        s = settings
        self.scalars = np.array([s.h, s.damping, s.offset, s.friction, s.contact_radius, s.max_step, s.thickness],
                                dtype=np.float64)
        self.threads = ThreadChooser.for_cores() if options.threads == "auto" else ThreadChooser([options.threads])

    def _f(self, a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a, dtype=self.dtype)

    def set_state(self, x: np.ndarray, v: np.ndarray) -> None:
        self.x, self.v = self._f(x).copy(), self._f(v).copy()

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x.astype(np.float64), self.v.astype(np.float64)

    def advance(self, frame: FrameInput) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f, s = self._f, self.settings
        body0, body1, n0, n1 = f(frame.body0), f(frame.body1), f(frame.normals0), f(frame.normals1)
        corners = np.ascontiguousarray(frame.corners, dtype=np.int32)
        pairs = np.ascontiguousarray(frame.pairs, dtype=np.int32)
        valid = np.ascontiguousarray(frame.pair_valid, dtype=np.uint8)
        res, c = np.empty(len(self.ci), self.dtype), np.empty(len(self.ci), self.dtype)
        self.threads.run(lambda threads: self.fn(
            len(self.x), len(body0), len(self.ci), len(self.groups), corners.shape[1], len(pairs),
            int(self.jacobi), int(s.self_collision), s.substeps, s.iterations,
            ctypes.c_void_p(_ptr(self.scalars)), threads, int(self.options.simd),
            *(ctypes.c_void_p(_ptr(a)) for a in (
                self.x, self.v, self.inv_mass, self.free, self.gravity, self.group_start, self.ci, self.cj,
                self.rest, self.alpha_t, self.share, self.inc_start, self.inc, body0, body1, n0, n1, corners,
                pairs, valid, res, c))))
        return (self.x.astype(np.float64), self.in_model_order([res.astype(np.float64)]),
                self.in_model_order([c.astype(np.float64)]))


class NativeXPBDSimulator(XPBDSimulator):
    """XPBD cloth as a compiled C++/OpenMP kernel (one call per frame)."""

    Options = NativeXPBDOptions
    options: NativeXPBDOptions

    def make_stepper(self, model: ClothModel, settings: StepSettings) -> Stepper:
        return NativeStepper(model, settings, self.options)
