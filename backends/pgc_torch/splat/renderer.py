"""The ``splat_renderer`` implementation 'torch'."""

from __future__ import annotations

import numpy as np
import torch

from pgc.cores import allotted_cores
from pgc.events import Reporter
from pgc.roles.splat_renderer import FitSplatsSettings, RenderOutput, SplatFit, SplatRenderer
from pgc.splats import fused as fused_kernel
from pgc.splats.fit import fit_splats
from pgc.splats.quaternion import quat_to_rotmat
from pgc.types import Camera, Capture, Mesh, WorldGaussians

from pgc_torch.specs_splat import TorchSplatOptions
from pgc_torch.threads import torch_threads

from .fit import TorchFitBackend
from .rasterizer import rasterize


class TorchSplatRenderer(SplatRenderer):
    """EWA splatting in torch: the fused compiled kernel, or pure torch where it does not build."""

    Options = TorchSplatOptions

    @property
    def compositor(self) -> str:
        """'fused' or 'torch': the rendering path this instance uses."""
        return fused_kernel.render_path(self.options.compositor, "torch")

    @property
    def threads(self) -> int:
        return self.options.threads or allotted_cores()

    def rasterize(self, means: torch.Tensor, rotmats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
                  sh: torch.Tensor, camera: Camera, background=None, sh_degree: int | None = None):
        """Differentiable render of torch world Gaussians: (colour (H, W, 3), alpha (H, W), depth (H, W))."""
        return rasterize(means, rotmats, scales, opacities, sh, camera, background, sh_degree, self.options.near,
                         self.options.tile_size, self.compositor, self.threads)

    def render(self, gaussians: WorldGaussians, camera: Camera, background: np.ndarray | None = None,
               sh_degree: int | None = None) -> RenderOutput:
        f32 = torch.float32
        with torch.no_grad(), torch_threads(1):
            color, alpha, depth = self.rasterize(
                torch.as_tensor(np.asarray(gaussians.means), dtype=f32),
                quat_to_rotmat(torch.as_tensor(np.asarray(gaussians.quats), dtype=torch.float64)).to(f32),
                torch.as_tensor(np.asarray(gaussians.scales), dtype=f32),
                torch.as_tensor(np.asarray(gaussians.opacities), dtype=f32),
                torch.as_tensor(np.asarray(gaussians.sh), dtype=f32), camera, background, sh_degree)
        return RenderOutput(color=color.numpy(), alpha=alpha.numpy(), depth=depth.numpy())

    def fit(self, capture: Capture, mesh: Mesh, settings: FitSplatsSettings | None = None,
            reporter: Reporter | None = None) -> SplatFit:
        return fit_splats(TorchFitBackend(self), capture, mesh, settings, reporter)
