"""onnx plugin for PGC. Keep this file light (no onnx import)."""
