"""Registration of the ONNX albedo estimator (light: pydantic only)."""

from __future__ import annotations

from pgc.options import Options
from pgc.registry import ImplementationSpec


class OnnxAlbedoOptions(Options):
    model: str | None = None
    """Path of an ONNX intrinsic-decomposition model following the PGC model contract (docs/albedo.md);
    None uses the small model shipped with PGC (trained on synthetic renders by scripts/train_albedo.py)."""
    tile: int | None = None
    """Tile size in pixels for large images; None takes the model's metadata (pgc_tile) or 256."""
    overlap: int | None = None
    """Overlap between tiles in pixels; None takes the model's metadata (pgc_overlap) or 32."""
    threads: int = 2
    """onnxruntime intra-op threads."""


SPECS = [
    ImplementationSpec(
        role="albedo_estimator", name="onnx", factory="pgc_onnx.albedo:OnnxAlbedoEstimator",
        options="pgc_onnx.specs_albedo:OnnxAlbedoOptions", requires=("onnxruntime",), extra="onnx",
        description="intrinsic-decomposition network on onnxruntime (CPU), tiled; ships a small model"),
]
