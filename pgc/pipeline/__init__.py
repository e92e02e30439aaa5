"""The pipeline: what runs the declared stages (:mod:`pgc.stages`; mesh -> garment -> fit_splats -> base_color ->
material -> asset; animate -> render -> eval) through one runner (:mod:`pgc.pipeline.runner`) and the stage
cache, the demo and its report (docs/architecture.md, "Stages: one name each").
"""
