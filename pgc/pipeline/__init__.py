"""The pipeline: stages (mesh -> splats -> albedo -> material -> asset; animate -> render -> compose -> eval).

Each stage's options model lives in a light module ``settings_<stage>.py`` exposing ``SETTINGS``
(stage name -> :class:`pgc.options.Options` subclass); :func:`pgc.config.stage_settings` gathers them.
"""
