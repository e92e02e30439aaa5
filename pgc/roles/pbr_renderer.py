"""Role ``pbr_renderer``: shades a mesh with a BRDF and lighting, in screen or texture space; fits materials.

Contract
- :meth:`render`: the mesh seen from ``camera`` -> :class:`pgc.roles.splat_renderer.RenderOutput`
  (linear RGB radiance over a black background, alpha = pixel coverage). ``occluder`` (e.g. the body)
  shadows the mesh and hides it where it is in front; it is not itself returned (zero colour and alpha).
- :meth:`render_texture`: outgoing radiance toward ``camera``'s centre at every texel centre of the mesh's
  UV atlas, (H, W, 3), plus the (H, W) coverage of the atlas (0 outside charts). Shadowing and indirect
  light are included where the implementation supports them (documented per implementation);
  ``occluder`` (e.g. the body under a garment) casts shadows on the mesh but is not itself returned.
- :meth:`fit`: fits the parameters of ``brdf`` (not the base-colour texture) and the RGB radiance of a
  constant environment light to ``capture`` on ``mesh``; returns the fitted material, light and figures.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pgc.events import Reporter
from pgc.roles._base import RoleImplementation
from pgc.roles.splat_renderer import RenderOutput
from pgc.types import Camera, Capture, Light, Material, Mesh


@dataclass
class MaterialFit:
    material: Material
    light: Light
    figures: dict[str, Any] = field(default_factory=dict)


class PBRRenderer(RoleImplementation, ABC):
    role = "pbr_renderer"

    @abstractmethod
    def render(self, mesh: Mesh, material: Material, light: Light, camera: Camera,
               occluder: Mesh | None = None) -> RenderOutput:
        """Render ``mesh`` with ``material`` under ``light`` from ``camera`` (``occluder``: see the contract)."""

    @abstractmethod
    def render_texture(self, mesh: Mesh, material: Material, light: Light, camera: Camera,
                       resolution: tuple[int, int], occluder: Mesh | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Radiance toward ``camera`` at each texel of the UV atlas: ((H, W, 3), (H, W) coverage)."""

    def fit(self, capture: Capture, mesh: Mesh, material: Material, settings: Any = None,
            reporter: Reporter | None = None) -> MaterialFit:
        """Fit ``material``'s BRDF parameters and the light to ``capture``. Optional for a renderer."""
        from pgc.errors import PGCPluginError

        raise PGCPluginError(f"pbr_renderer '{type(self).__name__}' cannot fit materials; use one that can "
                             "(e.g. 'mitsuba')")
