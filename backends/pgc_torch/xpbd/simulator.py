"""``xpbd-torch``: runs :func:`pgc.sim.xpbd.advance_frame` eagerly on torch tensors (CPU)."""

from __future__ import annotations

import numpy as np
import torch

from pgc.arrays import array_ops
from pgc.sim.driver import Stepper, XPBDSimulator
from pgc.sim.xpbd import FrameInput, Statics, StepSettings, advance_frame
from pgc.sim.model import ClothModel
from pgc.sim.options import XPBDOptions
from pgc_torch.threads import torch_threads

TORCH = array_ops("torch")


class TorchStepper(Stepper):
    def __init__(self, model: ClothModel, settings: StepSettings, options: XPBDOptions) -> None:
        super().__init__(model, settings, options)
        self.dtype = torch.float64 if options.dtype == "float64" else torch.float32
        free = (model.inv_mass > 0).astype(np.float64)
        self.statics = Statics(self._t(model.inv_mass), self._t(free),
                               tuple(tuple(self._t(a) for a in g) for g in self.groups),
                               self._t(np.array(options.gravity)))

    def _t(self, a: np.ndarray) -> torch.Tensor:
        a = np.asarray(a)
        if a.dtype.kind in "iu":
            return torch.from_numpy(a.astype(np.int64))
        if a.dtype == bool:
            return torch.from_numpy(a.copy())
        return torch.from_numpy(a.astype(np.float64)).to(self.dtype)

    def set_state(self, x: np.ndarray, v: np.ndarray) -> None:
        self.x, self.v = self._t(x), self._t(v)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x.double().numpy().copy(), self.v.double().numpy().copy()

    @torch.inference_mode()
    def advance(self, frame: FrameInput) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        inputs = FrameInput(*(self._t(a) for a in frame))
        with torch_threads(1):  # a few thousand rows per op: too small to split over threads
            self.x, self.v, res = advance_frame(TORCH, self.settings, self.statics, self.x, self.v, inputs)
        return (self.x.double().numpy().copy(), self.in_model_order([g[0].double().numpy() for g in res]),
                self.in_model_order([g[1].double().numpy() for g in res]))


class TorchXPBDSimulator(XPBDSimulator):
    """XPBD cloth in PyTorch (eager, vectorised over constraints and vertices)."""

    def make_stepper(self, model: ClothModel, settings: StepSettings) -> Stepper:
        return TorchStepper(model, settings, self.options)
