"""Training of the shipped albedo U-Net on synthetic renders (seeded and deterministic on the CPU).

Loss, on foreground pixels in sRGB space (what the network sees): L1 of the albedo plus L1 of its image
gradients (sharp pattern edges, flat shading-free regions), both after the best per-image, per-channel
scale of the prediction. Albedo and light are only known up to such a scale (the light's tint and
intensity vary across the training scenes; the pipeline's colour correction removes the scale), so the
network is asked for what can be inferred: the shading-free pattern. Augmentation: random crops, mirror,
and a random per-channel gain of the input (exposure and white balance; the scale-invariant loss makes
the target unchanged). Adam with a cosine decay.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from pgc.albedo.dataset import AlbedoData, scale_invariant_error
from pgc.events import Reporter
from pgc.io.images import linear_to_srgb
from pgc_torch.albedo.net import AlbedoUNet


@dataclass
class TrainSettings:
    steps: int = 1200
    batch: int = 8
    crop: int = 96
    lr: float = 2e-3
    width: int = 24
    gain: float = 0.25
    """Input gain per sample and channel, uniform in [1 - gain, 1 + gain] (sRGB values, clipped to 1)."""
    seed: int = 0


def _to_tensor(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(x)).permute(0, 3, 1, 2).contiguous()


def _masked_l1(a: torch.Tensor, b: torch.Tensor, m: torch.Tensor) -> torch.Tensor:
    return (m * (a - b).abs()).sum() / (3 * m.sum() + 1e-6)


def _loss(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    m = mask[:, None]
    scale = (m * pred * target).sum((2, 3), keepdim=True) / ((m * pred * pred).sum((2, 3), keepdim=True) + 1e-6)
    pred = pred * scale.detach()
    grad_x = _masked_l1(pred.diff(dim=-1), target.diff(dim=-1), m[..., :, 1:] * m[..., :, :-1])
    grad_y = _masked_l1(pred.diff(dim=-2), target.diff(dim=-2), m[..., 1:, :] * m[..., :-1, :])
    return _masked_l1(pred, target, m) + 0.5 * (grad_x + grad_y)


def train(data: AlbedoData, settings: TrainSettings, reporter: Reporter | None = None) -> AlbedoUNet:
    """Train the U-Net on ``data`` (linear images and albedo) and return it (eval mode)."""
    reporter = reporter or Reporter.silent()
    torch.manual_seed(settings.seed)
    rng = np.random.default_rng(settings.seed)
    x = _to_tensor(linear_to_srgb(np.clip(data.images, 0, 1)).astype(np.float32))
    y = _to_tensor(linear_to_srgb(np.clip(data.albedo, 0, 1)).astype(np.float32))
    m = torch.from_numpy(data.mask)
    model = AlbedoUNet(settings.width)
    opt = torch.optim.Adam(model.parameters(), lr=settings.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, settings.steps)
    n, _, h, w = x.shape
    c = min(settings.crop, h, w) // 4 * 4
    with reporter.stage("train_albedo", total=settings.steps) as st:
        for step in range(settings.steps):
            idx = rng.integers(0, n, settings.batch)
            oy, ox = rng.integers(0, h - c + 1), rng.integers(0, w - c + 1)
            xb, yb, mb = (t[idx][..., oy:oy + c, ox:ox + c] for t in (x, y, m))
            if rng.uniform() < 0.5:  # mirror augmentation
                xb, yb, mb = xb.flip(-1), yb.flip(-1), mb.flip(-1)
            if settings.gain > 0:
                gain = rng.uniform(1 - settings.gain, 1 + settings.gain, (settings.batch, 3, 1, 1))
                xb = (xb * torch.from_numpy(gain.astype(np.float32))).clamp(0.0, 1.0)
            loss = _loss(model(xb), yb, mb)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            if step % 25 == 0 or step == settings.steps - 1:
                st.progress(step + 1, loss=loss.item())
    return model.eval()


def evaluate(predict, data: AlbedoData) -> dict[str, float]:
    """Scale-invariant albedo error on the garment of the network and of the raw image used as albedo.
    ``predict(image, mask)`` gets the garment mask, as the texture stage passes it."""
    net, raw = [], []
    for i in range(len(data)):
        weight = (data.garment[i] > 0.5).astype(np.float64)
        pred = predict(data.images[i], weight)
        net.append(scale_invariant_error(pred, data.albedo[i], weight))
        raw.append(scale_invariant_error(data.images[i], data.albedo[i], weight))
    return {"albedo_error": float(np.mean(net)), "albedo_error_std": float(np.std(net)),
            "raw_image_error": float(np.mean(raw)), "raw_image_error_std": float(np.std(raw))}
