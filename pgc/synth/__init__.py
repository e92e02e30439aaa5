"""The synthetic capture generator: body, motions, garments, fabrics, dome rig, Mitsuba rendering and
ground truth (docs/synth.md). Submodules import their heavy dependencies (Mitsuba, pymeshlab, xatlas,
scikit-image) only when they run."""
