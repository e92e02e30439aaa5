"""The fused splat path in torch: :class:`FusedRasterize`, one ``torch.autograd.Function`` around the compiled
kernel of :mod:`pgc.splats.fused` (one call renders, one computes the gradients of all five inputs), so a fit
step builds no graph of per-Gaussian torch ops."""

from __future__ import annotations

import torch

from pgc.splats import fused as kernel
from pgc.types import Camera

__all__ = ["FusedRasterize"]


def _arrays(tensors) -> list:
    """Zero-copy numpy views of contiguous CPU tensors."""
    return [t.detach().contiguous().numpy() for t in tensors]


class FusedRasterize(torch.autograd.Function):
    """World Gaussians -> (colour (H, W, 3), alpha (H, W), weighted depth sum (H, W)) in one compiled call.

    Differentiable w.r.t. means (N, 3), rotmats (N, 3, 3), scales (N, 3), opacities (N,) and sh (N, K, 3);
    float32 or float64 (every tensor in the dtype of ``means``). ``count`` = SH coefficients used.
    """

    @staticmethod
    def forward(ctx, means, rotmats, scales, opacities, sh, camera: Camera, background: torch.Tensor, count: int,
                near: float, tile: int, threads: int):
        dtype = means.dtype
        inputs = [x.detach().to(dtype).contiguous() for x in (means, rotmats, scales, opacities, sh)]
        cam = kernel.camera_vector(camera, near)
        bg = background.to(dtype).contiguous()
        # inputs were checked at the role's entry (SplatRenderer.render) or made by the fit itself: no second pass
        out = kernel.forward(_arrays(inputs), cam, bg.numpy(), camera.height, camera.width, count, tile, threads,
                             check_finite=False)
        ctx.save_for_backward(*inputs)
        ctx.state = (cam, bg, out.workspace, count, threads)
        return tuple(torch.from_numpy(x) for x in (out.color, out.alpha, out.depth_sum))

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, g_color, g_alpha, g_dsum):
        cam, bg, ws, count, threads = ctx.state
        g = [None if x is None else x.detach().contiguous().numpy() for x in (g_color, g_alpha, g_dsum)]
        grads = kernel.backward(ws, _arrays(ctx.saved_tensors), cam, bg.numpy(), *g, count, threads)
        return (*(torch.from_numpy(x) for x in grads), None, None, None, None, None, None)
