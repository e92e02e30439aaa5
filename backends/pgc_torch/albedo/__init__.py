"""The small intrinsic-decomposition network that PGC trains on its synthetic renders and ships as ONNX."""
