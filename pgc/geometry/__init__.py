"""Backend-independent geometry (numpy/scipy only): rasterisation, visual hull, multi-view stereo depth,
garment label voting and mesh quality metrics. Used by every reconstructor."""
