"""Registration of the ONNX albedo estimator (light: pydantic only)."""

from __future__ import annotations

from pgc.options import MAX_THREADS, Options, count
from pgc.registry import ImplementationSpec


class OnnxAlbedoOptions(Options):
    model: str | None = None
    """Path of an ONNX intrinsic-decomposition model following the PGC model contract (docs/albedo.md);
    None uses the small model shipped with PGC (trained on synthetic renders by scripts/train_albedo.py)."""
    tile: int | None = count(None, 1, 16384, "tile size (px)")
    """Tile size in pixels for large images; None takes the model's metadata (pgc_tile) or 256."""
    overlap: int | None = count(None, 0, 8192, "tile overlap (px)")
    """Overlap between tiles in pixels; None takes the model's metadata (pgc_overlap) or 32."""
    threads: int = count(2, 0, MAX_THREADS, "onnxruntime intra-op threads")
    """onnxruntime intra-op threads."""
    shading_kernel: int = count(13, 0, 1023, "Retinex shading low-pass size (odd px); 0 = off")
    """Retinex prior on the prediction: the shading it implies (image / albedo) is low-passed with the
    mask-aware Gaussian of the filter role (odd size in px, sigma = size / 6) and the albedo re-derived as
    image / smoothed shading, so the image's own high frequencies (pattern edges) are kept and the network's
    pixel-level errors dropped; 0 = the raw prediction. 13 px (sigma 2 px at the 256 px training size) was
    chosen on the training garment (docs/albedo.md)."""


SPECS = [
    ImplementationSpec(
        role="albedo_estimator", name="onnx", factory="pgc_onnx.albedo:OnnxAlbedoEstimator",
        options="pgc_onnx.specs_albedo:OnnxAlbedoOptions", requires=("onnxruntime",), extra="onnx",
        description="intrinsic-decomposition network on onnxruntime (CPU), tiled; ships a small model"),
]
