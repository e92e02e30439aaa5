"""Role ``calibrator``: refine the camera poses of a capture from its images.

Contract
- Input: a :class:`pgc.types.Capture` whose cameras are roughly calibrated (intrinsics known, poses
  approximate) with at least 3 views.
- Output: :class:`Calibration` whose ``capture`` has the same views in the same order with the same names,
  images, masks and intrinsics; only the poses (``R``, ``t``) change, expressed in the input's frame and
  scale (world metres). Views the method could not register keep their input pose. Every number is finite.
- ``figures`` holds measured numbers (registered views, reprojection error in pixels, pose changes).
- Bad input (fewer than 3 views, images without enough matching features) raises ``PGCDataError``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

from pgc.events import Reporter
from pgc.roles._base import RoleImplementation
from pgc.types import Capture


@dataclass
class Calibration:
    capture: Capture
    figures: dict[str, Any] = field(default_factory=dict)


class Calibrator(RoleImplementation, ABC):
    role = "calibrator"

    @abstractmethod
    def calibrate(self, capture: Capture, reporter: Reporter | None = None) -> Calibration:
        """``capture`` with refined camera poses, and figures."""
