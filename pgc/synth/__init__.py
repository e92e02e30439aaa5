"""The synthetic capture generator: body, motions, garments, fabrics, dome rig, rendering through the
configured ``scene_renderer`` and ground truth (docs/synth.md), and the albedo network's training set. A client
of the core: no core module, backend or plugin imports it. Submodules import their heavy dependencies
(Mitsuba, pymeshlab, xatlas, scikit-image) only when they run."""
