"""The ``metric`` role 'lpips': numpy linear RGB in, the LPIPS distance out (lower is better)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from pgc.io.images import linear_to_srgb
from pgc.metrics.common import mask_bbox
from pgc.metrics.weights import lpips_weights_path
from pgc.roles.metric import Metric
from pgc_torch.lpips.network import MIN_SIZE, LPIPSNetwork
from pgc_torch.specs_lpips import LPIPSOptions
from pgc_torch.threads import torch_threads


@lru_cache(maxsize=2)
def load_network(net: str) -> LPIPSNetwork:
    """The LPIPS network of backbone ``net`` with its converted weights (loaded once per process)."""
    return LPIPSNetwork(net, lpips_weights_path(net))


class LPIPSMetric(Metric):
    """LPIPS v0.1 on sRGB-encoded values. With a mask: the images are cropped to the mask's bounding box (grown
    to the backbone's minimum size) and each layer's distance map is averaged with the mask as weights; an
    image smaller than that minimum is padded to it by repeating its edge pixels, the padding outside the mask.
    Runs on one torch thread: the images are small, and OpenMP barriers between contended threads cost several
    times the convolutions (the tiny demo's LPIPS values came out bit-identical)."""

    name = "lpips"
    Options = LPIPSOptions
    higher_is_better = False

    def min_image_size(self, masked: bool) -> tuple[int, str]:
        """The backbone's smallest input without a mask; with one, any size (the crop is padded to it)."""
        if masked:
            return 1, "one pixel"
        return MIN_SIZE[self.options.net], f"the '{self.options.net}' backbone's downsampling layers"

    def compute(self, pred: np.ndarray, target: np.ndarray, mask: np.ndarray | None) -> float:
        network = load_network(self.options.net)
        if mask is not None:
            rows, cols = mask_bbox(mask, MIN_SIZE[self.options.net])
            pred, target, mask = pred[rows, cols], target[rows, cols], np.asarray(mask)[rows, cols]
            pad = [(0, max(0, MIN_SIZE[self.options.net] - n)) for n in mask.shape]
            if any(after for _, after in pad):
                pred, target = (np.pad(x, pad + [(0, 0)], mode="edge") for x in (pred, target))
                mask = np.pad(mask, pad)
        with torch_threads(1):
            return network.distance(linear_to_srgb(pred), linear_to_srgb(target), mask)
