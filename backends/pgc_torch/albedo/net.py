"""A small U-Net predicting albedo (sRGB, [0, 1]) from an sRGB image: two downsamplings, so H and W must be
multiples of 4, and a receptive-field radius of about 22 px (tiles overlap by 64 px; see pgc_onnx.albedo)."""

from __future__ import annotations

import torch
from torch import nn

MULTIPLE_OF = 4
TILE = 256
OVERLAP = 64


def _block(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, padding=1), nn.ReLU(inplace=True),
                         nn.Conv2d(cout, cout, 3, padding=1), nn.ReLU(inplace=True))


class AlbedoUNet(nn.Module):
    def __init__(self, width: int = 24) -> None:
        super().__init__()
        w = width
        self.enc0, self.enc1, self.enc2 = _block(3, w), _block(w, 2 * w), _block(2 * w, 4 * w)
        self.up1 = nn.ConvTranspose2d(4 * w, 2 * w, 2, stride=2)
        self.dec1 = _block(4 * w, 2 * w)
        self.up0 = nn.ConvTranspose2d(2 * w, w, 2, stride=2)
        self.dec0 = _block(2 * w, w)
        self.head = nn.Conv2d(w, 3, 1)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        e0 = self.enc0(image)
        e1 = self.enc1(nn.functional.avg_pool2d(e0, 2))
        e2 = self.enc2(nn.functional.avg_pool2d(e1, 2))
        d1 = self.dec1(torch.cat([self.up1(e2), e1], 1))
        d0 = self.dec0(torch.cat([self.up0(d1), e0], 1))
        # Predict a multiplicative correction of the input (albedo = image x ratio is the easy prior).
        return torch.sigmoid(self.head(d0) + torch.logit(image.clamp(0.02, 0.98)))


def export_onnx(model: AlbedoUNet, path: str, metadata: dict[str, str] | None = None) -> None:
    """Export with dynamic H, W and the PGC model-contract metadata."""
    import onnx

    model = model.eval()
    dummy = torch.rand(1, 3, 64, 64)
    torch.onnx.export(model, (dummy,), path, input_names=["image"], output_names=["albedo"],
                      dynamic_axes={"image": {0: "n", 2: "h", 3: "w"}, "albedo": {0: "n", 2: "h", 3: "w"}},
                      opset_version=17, dynamo=False)
    proto = onnx.load(path)
    meta = {"pgc_contract_version": "1", "pgc_multiple_of": str(MULTIPLE_OF), "pgc_input_space": "srgb",
            "pgc_output_space": "srgb", "pgc_tile": str(TILE), "pgc_overlap": str(OVERLAP), **(metadata or {})}
    del proto.metadata_props[:]
    for k, v in meta.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = k, v
    onnx.save(proto, path)
