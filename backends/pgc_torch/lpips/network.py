"""The LPIPS network (Zhang et al. 2018, v0.1 linear heads) as plain torch functions over loaded weights.

Layers follow torchvision's AlexNet / VGG16 feature stacks; the taps are the ReLU outputs LPIPS uses
(AlexNet relu1..5; VGG relu1_2, relu2_2, relu3_3, relu4_3, relu5_3). Inputs are sRGB-encoded images in
[0, 1], mapped to [-1, 1] and then by LPIPS's scaling layer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from pgc.errors import PGCDataError

# ("conv", stride, padding) | ("pool", size, stride) | ("tap",)
_ALEX = (("conv", 4, 2), ("tap",), ("pool", 3, 2), ("conv", 1, 2), ("tap",), ("pool", 3, 2),
         ("conv", 1, 1), ("tap",), ("conv", 1, 1), ("tap",), ("conv", 1, 1), ("tap",))
_VGG = tuple(layer for block, convs in enumerate((2, 2, 3, 3, 3))
             for layer in ((("pool", 2, 2),) if block else ()) + (("conv", 1, 1),) * convs + (("tap",),))
LAYERS = {"alex": _ALEX, "vgg": _VGG}
MIN_SIZE = {"alex": 32, "vgg": 16}
"""Smallest image side (px) each backbone accepts (AlexNet's strided conv and two pools need 31)."""
_SHIFT = (-0.030, -0.088, -0.188)
_SCALE = (0.458, 0.448, 0.450)


class LPIPSNetwork:
    """LPIPS distance with backbone ``net`` ('alex' or 'vgg') from ``weights`` (a dict or an ``.npz`` path)."""

    def __init__(self, net: str, weights: dict[str, np.ndarray] | str | Path) -> None:
        if not isinstance(weights, dict):
            with np.load(weights, allow_pickle=False) as data:
                weights = {k: data[k] for k in data.files}
        self.net = net
        self.layers = LAYERS[net]
        self.params = {k: torch.from_numpy(np.asarray(v, np.float32)) for k, v in weights.items()}
        expected = sum(layer[0] == "conv" for layer in self.layers)
        if f"conv{expected - 1}.weight" not in self.params or f"conv{expected}.weight" in self.params:
            raise PGCDataError(f"lpips: weights for '{net}' must hold exactly {expected} conv layers")
        self.shift = torch.tensor(_SHIFT).view(1, 3, 1, 1)
        self.scale = torch.tensor(_SCALE).view(1, 3, 1, 1)

    def features(self, x: torch.Tensor) -> list[torch.Tensor]:
        """Tapped activations of ``x`` (N, 3, H, W), already scaled."""
        taps, conv = [], 0
        for layer in self.layers:
            if layer[0] == "conv":
                x = F.relu(F.conv2d(x, self.params[f"conv{conv}.weight"], self.params[f"conv{conv}.bias"],
                                    stride=layer[1], padding=layer[2]))
                conv += 1
            elif layer[0] == "pool":
                x = F.max_pool2d(x, layer[1], layer[2])
            else:
                taps.append(x)
        return taps

    def layer_maps(self, srgb0: torch.Tensor, srgb1: torch.Tensor) -> list[torch.Tensor]:
        """Per-layer distance maps (N, 1, h_l, w_l) of sRGB images (N, 3, H, W) in [0, 1]."""
        x0, x1 = ((2.0 * s - 1.0 - self.shift) / self.scale for s in (srgb0, srgb1))
        maps = []
        for j, (f0, f1) in enumerate(zip(self.features(x0), self.features(x1))):
            f0 = f0 / (torch.sqrt((f0 ** 2).sum(1, keepdim=True)) + 1e-10)
            f1 = f1 / (torch.sqrt((f1 ** 2).sum(1, keepdim=True)) + 1e-10)
            maps.append(((f0 - f1) ** 2 * self.params[f"lin{j}.weight"].view(1, -1, 1, 1)).sum(1, keepdim=True))
        return maps

    def distance(self, srgb0: np.ndarray, srgb1: np.ndarray, mask: np.ndarray | None = None) -> float:
        """LPIPS of two sRGB images (H, W, 3) in [0, 1]; with ``mask`` (H, W) the masked mean of each layer's
        map (the mask area-resampled to that layer), summed over layers. Without a mask: the standard LPIPS."""
        h, w = srgb0.shape[:2]
        if min(h, w) < MIN_SIZE[self.net]:
            raise PGCDataError(f"lpips: images of {h}x{w} px are too small for the '{self.net}' backbone "
                               f"(at least {MIN_SIZE[self.net]} px a side)")
        t0, t1 = (torch.from_numpy(np.ascontiguousarray(s, np.float32)).permute(2, 0, 1)[None] for s in (srgb0, srgb1))
        m = None if mask is None else torch.from_numpy(np.asarray(mask, np.float32))[None, None]
        total = 0.0
        with torch.no_grad():
            for layer_map in self.layer_maps(t0, t1):
                if m is None:
                    total += float(layer_map.mean())
                else:
                    weights = F.interpolate(m, size=layer_map.shape[-2:], mode="area")
                    total += float((layer_map * weights).sum() / weights.sum().clamp_min(1e-12))
        return total

    def distance_linear(self, linear0: np.ndarray, linear1: np.ndarray, mask: np.ndarray | None = None) -> float:
        """:meth:`distance` of linear RGB images (encoded to sRGB first, as the metric role specifies)."""
        from pgc.io.images import linear_to_srgb

        return self.distance(linear_to_srgb(linear0), linear_to_srgb(linear1), mask)
