"""PyTorch backend: splat rasteriser and fit, XPBD, filter, BRDF evaluation, fast PBR shading.

Keep this file light: registration must not import torch.
"""
