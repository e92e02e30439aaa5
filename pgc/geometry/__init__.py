"""Backend-independent geometry (numpy/scipy only): rasterisation, visual hull, multi-view stereo depth,
garment label voting, mesh quality metrics (used by every reconstructor; the built-in ones are in
:mod:`pgc.builtin_plugins.reconstructors`), and what is embedded in a mesh and follows it
(:mod:`pgc.geometry.embedded`)."""
