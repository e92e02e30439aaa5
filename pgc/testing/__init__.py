"""Testing kit for plugin authors: an isolated registry fixture, per-role conformance suites, and small scenes
made in-process for tests and benchmarks (``capture_scenes``, ``cloth_scenes``, ``pbr_scenes``)."""
