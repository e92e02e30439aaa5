"""The pipeline: stages (mesh -> garment -> fit_splats -> base_color -> material -> asset; animate -> render ->
eval), cached by content (docs/architecture.md, "Stages: one name each").

The options of the pipeline-only stages live in light modules ``settings_<stage>.py``; :data:`pgc.config.STAGES`
names every stage's options model.
"""
