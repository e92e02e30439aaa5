"""The ``material`` stage's options: the PBR renderer role's material-fit settings."""

from pgc.roles.pbr_renderer import MaterialFitSettings

SETTINGS = {"material": MaterialFitSettings}
