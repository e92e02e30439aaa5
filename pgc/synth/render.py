"""The synthetic scene's renderer: the ``scene_renderer`` role that the run configuration chooses
(``[scene_renderer]``; default: Mitsuba 3 on the CPU). :func:`scene_renderer` builds it; the generator's
functions that render take it as an argument. What it renders (:class:`pgc.roles.scene_renderer.SceneGeometry`)
and the renderer-independent ground-truth helpers live with the role in :mod:`pgc.roles.scene_renderer`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pgc.config import RunConfig
    from pgc.roles.scene_renderer import SceneRenderer


def scene_renderer(cfg: RunConfig) -> SceneRenderer:
    """The scene renderer ``cfg`` chooses (``[scene_renderer]``), built with its options; none registered raises
    :class:`pgc.errors.PGCPluginError` naming the extra to install."""
    from pgc.errors import PGCPluginError

    if "scene_renderer" not in cfg.roles:
        raise PGCPluginError("no scene_renderer is registered (the synthetic scene is path traced by the "
                             "Mitsuba backend); install with: pip install 'pgc[mitsuba]'")
    return cfg.create("scene_renderer")
