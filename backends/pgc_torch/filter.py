"""Alpha-aware low-pass in PyTorch: two depthwise 1-D convolutions (O(k) per pixel), differentiable.

``alpha_lowpass`` works on tensors and stays inside torch (for composition in the torch backend);
:class:`TorchFilter` is the ``filter`` role implementation (numpy in, numpy out).
"""

from __future__ import annotations

import numpy as np
import torch

from pgc.filtering.kernel import check_kernel_size, gaussian_kernel_1d, renormalise
from pgc.roles.filter import Filter
from pgc_torch.specs_filter import TorchFilterOptions


def alpha_lowpass(image: torch.Tensor, alpha: torch.Tensor, kernel_size: int) -> torch.Tensor:
    """Alpha-aware Gaussian low-pass of ``image`` (H, W, C) weighted by ``alpha`` (H, W); same dtype/device.

    Blurs ``[alpha * image, alpha]`` with zero borders in two passes and renormalises (see
    :func:`pgc.filtering.kernel.renormalise`). Differentiable in ``image`` and ``alpha``.
    """
    kernel_size = check_kernel_size(kernel_size)
    channels = image.shape[-1] + 1
    stack = torch.cat([image * alpha[..., None], alpha[..., None]], dim=-1)
    x = stack.permute(2, 0, 1).unsqueeze(0)  # (1, C + 1, H, W)
    taps = torch.as_tensor(gaussian_kernel_1d(kernel_size), dtype=image.dtype, device=image.device)
    r = kernel_size // 2
    x = torch.nn.functional.conv2d(x, taps.view(1, 1, 1, -1).expand(channels, 1, 1, kernel_size),
                                   padding=(0, r), groups=channels)
    x = torch.nn.functional.conv2d(x, taps.view(1, 1, -1, 1).expand(channels, 1, kernel_size, 1),
                                   padding=(r, 0), groups=channels)
    blurred = x[0].permute(1, 2, 0)
    return renormalise(blurred[..., :-1], blurred[..., -1:], image)


class TorchFilter(Filter):
    """``filter`` 'torch': float32 separable convolution on the CPU (or ``options.device``)."""

    Options = TorchFilterOptions

    def lowpass(self, image: np.ndarray, alpha: np.ndarray, kernel_size: int) -> np.ndarray:
        device = torch.device(self.options.device)
        with torch.no_grad():
            out = alpha_lowpass(torch.from_numpy(image).to(device), torch.from_numpy(alpha).to(device), kernel_size)
        return out.cpu().numpy().astype(np.float32, copy=False)
