"""LPIPS (Zhang et al. 2018) in PyTorch with the AlexNet / VGG16 backbones and the v0.1 linear heads."""
