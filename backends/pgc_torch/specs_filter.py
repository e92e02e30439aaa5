"""Registration of the torch ``filter`` (light: pgc core and pydantic only)."""

from __future__ import annotations

from pydantic import Field

from pgc.options import Options
from pgc.registry import ImplementationSpec


class TorchFilterOptions(Options):
    device: str = Field("cpu", description="torch device the blur runs on, e.g. 'cpu' or 'cuda'")


SPECS = [
    ImplementationSpec(
        role="filter", name="torch", factory="pgc_torch.filter:TorchFilter",
        description="alpha-aware Gaussian low-pass, separable depthwise conv2d in PyTorch (differentiable)",
        options="pgc_torch.specs_filter:TorchFilterOptions", requires=("torch",), extra="torch"),
]
