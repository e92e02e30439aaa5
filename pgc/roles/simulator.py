"""Role ``simulator``: garment rest mesh + body motion -> garment vertex positions per frame.

Contract
- ``garment``: the rest shape (metres), as reconstructed in the capture pose.
- ``motion``: :class:`pgc.types.BodyMotion` whose frame 0 is the capture pose (the body the garment was
  reconstructed on); the simulator blends in from it so the first frames do not explode.
- Output :class:`Simulation`: ``vertices`` (T, V, 3) float32, one row per motion frame, the garment's
  state at the end of each frame; finite always. ``figures``: residuals, penetration counts, timings.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pgc.events import Reporter
from pgc.roles._base import RoleImplementation
from pgc.types import BodyMotion, Mesh


@dataclass
class Simulation:
    vertices: np.ndarray
    figures: dict[str, Any] = field(default_factory=dict)


class Simulator(RoleImplementation, ABC):
    role = "simulator"

    @abstractmethod
    def simulate(self, garment: Mesh, motion: BodyMotion, reporter: Reporter | None = None) -> Simulation:
        """Simulate ``garment`` on the body of ``motion``."""
