"""The ``fit_splats`` stage's options: the splat renderer role's fit settings."""

from pgc.roles.splat_renderer import FitSplatsSettings

SETTINGS = {"fit_splats": FitSplatsSettings}
