"""Role ``reconstructor``: a capture -> the full-body mesh of the capture pose, with UVs and garment labels.

Contract
- Input: a :class:`pgc.types.Capture` with calibrated cameras, foreground masks and garment segmentation.
- Output: :class:`Reconstruction` whose ``mesh`` is a single watertight-ish surface in world metres,
  faces counter-clockwise seen from outside, simulation quality (roughly uniform edge lengths, no
  degenerate triangles), with a non-overlapping UV atlas (``uv``/``face_uv``) and per-face labels
  (``face_labels``, ids of ``Capture.labels``) from multi-view voting of the segmentation.
- ``figures`` holds measured numbers (seconds per step, vertex counts, minimum angle, ...).
- Bad input (too few views, empty masks, cameras that miss the object) raises ``PGCDataError``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

from pgc.events import Reporter
from pgc.roles._base import RoleImplementation
from pgc.types import Capture, Mesh


@dataclass
class Reconstruction:
    mesh: Mesh
    figures: dict[str, Any] = field(default_factory=dict)


class Reconstructor(RoleImplementation, ABC):
    role = "reconstructor"

    @abstractmethod
    def reconstruct(self, capture: Capture, reporter: Reporter | None = None) -> Reconstruction:
        """Reconstruct the labelled, UV-mapped full-body mesh of ``capture``."""
