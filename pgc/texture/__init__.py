"""Texture space: UV-atlas rasterisation, back-projection of views, colour correction, merging."""
