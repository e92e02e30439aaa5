"""The torch arrays of the splat fit: :class:`TorchFitBackend` for the loop of :mod:`pgc.splats.fit`.

Parameters are float32 leaf tensors bound to the fixed face frames of the mesh (:mod:`pgc.splats.binding`); a step
renders one view through the renderer's differentiable :meth:`rasterize`, takes the loss's gradient by autograd and
applies the shared Adam update. torch runs on one intra-op thread meanwhile (:func:`pgc_torch.threads.torch_threads`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ContextManager, Sequence

import numpy as np
import torch

from pgc.io.images import linear_to_srgb
from pgc.metrics.ssim import mean_ssim
from pgc.roles.splat_renderer import FitSplatsSettings
from pgc.splats.binding import apply_frames, triangle_frames
from pgc.splats.fit import ADAM_B1, ADAM_B2, ADAM_EPS, PARAMETERS, FitBackend, FitView
from pgc.splats.sh import SH_C0
from pgc.types import Camera, GaussianSet, Mesh
from pgc_torch.threads import torch_threads


@dataclass
class _Arrays:
    """A view's tensors."""

    camera: Camera
    target: torch.Tensor            # (H, W, 3) sRGB
    background: torch.Tensor        # (H, W, 3) linear
    mask: torch.Tensor | None       # (H, W)
    band: torch.Tensor | None       # (H, W)


class TorchFitBackend(FitBackend):
    """Torch tensors, autograd and the renderer's rasteriser for the shared fit loop."""

    name = "torch"

    def __init__(self, renderer: Any) -> None:
        self.renderer = renderer
        self.params: dict[str, torch.Tensor] = {}
        self.moments: dict[str, tuple[torch.Tensor, torch.Tensor]] = {}

    def session(self) -> ContextManager[None]:
        return torch_threads(1)

    def start(self, initial: GaussianSet, mesh: Mesh) -> None:
        tau, R, k = triangle_frames(torch.as_tensor(mesh.vertices), torch.as_tensor(mesh.faces))
        self.frames = (tau.float(), R.float(), k.float())
        self.parent = torch.as_tensor(initial.parent)
        self.params = {n: torch.tensor(getattr(initial, n), dtype=torch.float32).requires_grad_(True)
                       for n in PARAMETERS}
        self.moments = {n: (torch.zeros_like(p), torch.zeros_like(p)) for n, p in self.params.items()}
        self.scratch = {n: torch.empty_like(p) for n, p in self.params.items()}

    def prepare(self, view: FitView) -> _Arrays:
        def tensor(a: np.ndarray | None) -> torch.Tensor | None:
            return None if a is None else torch.as_tensor(a, dtype=torch.float32)

        return _Arrays(view.camera, tensor(view.target), tensor(view.background), tensor(view.mask),
                       tensor(view.band))

    def _world(self, keep: torch.Tensor | None = None) -> tuple[torch.Tensor, ...]:
        p = self.params
        world = (*apply_frames(*self.frames, self.parent, p["means"], p["quats"], p["log_scales"],
                               p["opacity_logits"]), p["sh"])
        return world if keep is None else tuple(t[keep] for t in world)

    def step(self, handle: _Arrays, degree: int, lrs: dict[str, Any], t: int,
             s: FitSplatsSettings) -> tuple[torch.Tensor, torch.Tensor]:
        color, alpha, _ = self.renderer.rasterize(*self._world(), handle.camera, handle.background, degree)
        pred = linear_to_srgb(color)
        loss = (s.lambda_l1 * (pred - handle.target).abs().mean()
                + (1 - s.lambda_l1) * (1 - mean_ssim(pred, handle.target)))
        if handle.mask is not None and s.lambda_mask > 0:
            loss = loss + s.lambda_mask * (handle.band * (handle.mask - alpha).abs()).mean()
        if s.lambda_surface > 0:  # local column 1 is the triangle normal
            loss = loss + s.lambda_surface * (self.params["means"][:, 1] ** 2).mean()
        if s.lambda_opacity > 0:
            loss = loss + s.lambda_opacity * torch.sigmoid(self.params["opacity_logits"]).mean()
        for p in self.params.values():
            p.grad = None
        loss.backward()
        with torch.no_grad():
            for name, p in self.params.items():
                adam_update_in_place(p, p.grad, *self.moments[name], t, torch.as_tensor(lrs[name], dtype=p.dtype),
                                     self.scratch[name], s.adam_eps)
            mse = ((pred - handle.target) ** 2).mean()
        return loss.detach(), mse

    def render(self, handle: _Arrays, degree: int, keep: np.ndarray | None = None) -> np.ndarray:
        with torch.no_grad():
            world = self._world(None if keep is None else torch.as_tensor(keep))
            return self.renderer.rasterize(*world, handle.camera, handle.background, degree)[0].numpy()

    def contributions(self, handles: Sequence[_Arrays], degree: int) -> np.ndarray:
        """Each Gaussian's weight as the gradient of the red channel's sum w.r.t. a DC colour probe."""
        total = torch.zeros(len(self.parent))
        with torch.no_grad():
            means, rot, scales, opac, _ = self._world()
        for h in handles:
            probe = torch.zeros(len(total), 1, 3).requires_grad_(True)  # colour = probe * C0 + 0.5
            color, _, _ = self.renderer.rasterize(means, rot, scales, opac, probe, h.camera, h.background, 0)
            color[..., 0].sum().backward()
            total += probe.grad[:, 0, 0] / SH_C0
        return total.numpy()

    def state(self) -> dict[str, np.ndarray]:
        out = {"parent": self.parent.numpy().copy()}
        out |= {f"p_{n}": p.detach().numpy().copy() for n, p in self.params.items()}
        for n, (m, v) in self.moments.items():
            out[f"m_{n}"], out[f"v_{n}"] = m.numpy().copy(), v.numpy().copy()
        return out

    def load_state(self, arrays: dict[str, np.ndarray]) -> None:
        self.parent = torch.as_tensor(np.asarray(arrays["parent"], np.int64))
        with torch.no_grad():
            for n, p in self.params.items():
                p.copy_(torch.as_tensor(arrays[f"p_{n}"]))
        self.moments = {n: (torch.as_tensor(arrays[f"m_{n}"]).clone(), torch.as_tensor(arrays[f"v_{n}"]).clone())
                        for n in PARAMETERS}

    def gaussians(self) -> GaussianSet:
        return GaussianSet(parent=self.parent.numpy(), **{n: p.detach().numpy() for n, p in self.params.items()})


def adam_update_in_place(p: torch.Tensor, g: torch.Tensor, m: torch.Tensor, v: torch.Tensor, t: int,
                         lr: torch.Tensor | float, scratch: torch.Tensor, eps: float = ADAM_EPS) -> None:
    """:func:`pgc.splats.fit.adam_update` on contiguous torch tensors of one shape, in place: updates ``p``,
    ``m`` and ``v``, overwrites ``g`` and ``scratch`` (a buffer of ``p``'s shape) and allocates nothing. The
    same operations in the same order as the reference (the same bits); a per-coefficient ``lr`` (the SH bands'
    (K, 1)) is spread over each row once instead of broadcast over (N, K, 3). On 18k Gaussians at SH degree 3
    the reference took 10 ms a step, most of it in allocating and first touching its ten temporaries."""
    shape = p.shape
    p, g, m, v, scratch = (x.view(len(x), -1) for x in (p, g, m, v, scratch))
    if isinstance(lr, torch.Tensor) and lr.ndim:
        lr = lr.expand(shape[1:]).reshape(1, -1)
    m.mul_(ADAM_B1).add_(torch.mul(g, 1.0 - ADAM_B1, out=scratch))
    v.mul_(ADAM_B2).add_(torch.mul(g, 1.0 - ADAM_B2, out=scratch).mul_(g))
    denom = torch.div(v, 1.0 - ADAM_B2 ** t, out=scratch).sqrt_().add_(eps)
    step = torch.div(m, 1.0 - ADAM_B1 ** t, out=g).mul_(lr)
    p.sub_(step.div_(denom))
