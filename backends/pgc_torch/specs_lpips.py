"""Registration of the torch LPIPS metric (light: pgc core and pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pgc.options import Options
from pgc.registry import ImplementationSpec


class LPIPSOptions(Options):
    net: Literal["alex", "vgg"] = Field(
        "alex", description="backbone: 'alex' (shipped) or 'vgg' (made by scripts/convert_lpips_weights.py)")


SPECS = [
    ImplementationSpec(
        role="metric", name="lpips", factory="pgc_torch.lpips.metric:LPIPSMetric",
        description="LPIPS v0.1 (AlexNet or VGG16 backbone) in PyTorch, on sRGB values; lower is better",
        options="pgc_torch.specs_lpips:LPIPSOptions", requires=("torch",), extra="torch"),
]
