"""How the near field's detail enters the hybrid: ``I = l(S) + g * h(G)`` with a per-pixel, per-channel gain g.

- ``additive`` (the paper): ``g = 1``, so ``I = h(G) + l(S)``. The detail keeps the amplitude it had under the
  capture light, whatever light the far field is rendered under.
- ``multiplicative``: ``g = l(S) / l(G)``, so ``I = l(S) * G / l(G)``: the near field's detail is a ratio to
  its own low band, and it follows the far field's shading (a light twice as bright on the far field doubles
  the detail). The denominator is guarded: ``g = min(l(S) / max(l(G), GAIN_FLOOR), MAX_GAIN)``, finite
  everywhere (``l(G) = 0`` where the Gaussians do not cover, a black near field), exact where ``l(G) >=
  GAIN_FLOOR`` and the ratio is below ``MAX_GAIN``.
Both modes give ``I = G`` where ``l(S) = l(G)`` (the far field matches the near field's low band, as at the
capture pose under the capture light). Arrays are un-premultiplied linear RGB (H, W, 3); numpy only.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

DetailMode = Literal["additive", "multiplicative"]
DETAIL_MODES: tuple[str, ...] = ("additive", "multiplicative")
GAIN_FLOOR = 1e-3
"""Smallest near-field low band (linear radiance) the multiplicative gain divides by."""
MAX_GAIN = 16.0
"""Largest multiplicative gain (a far field 16 x brighter than the near field's low band)."""


def detail_gain(low_far: np.ndarray, low_near: np.ndarray, mode: str) -> np.ndarray | float:
    """The gain g of the near field's high band ``h(G)`` in the hybrid ``l(S) + g h(G)`` (module docstring):
    1 for ``additive``, the guarded ratio ``l(S) / l(G)`` (float32, shape of the inputs) for
    ``multiplicative``."""
    if mode == "additive":
        return 1.0
    if mode != "multiplicative":
        raise ValueError(f"detail mode must be one of {DETAIL_MODES}, not {mode!r}")
    low_far = np.maximum(np.asarray(low_far, np.float32), 0.0)
    low_near = np.maximum(np.asarray(low_near, np.float32), GAIN_FLOOR)
    return np.minimum(low_far / low_near, MAX_GAIN).astype(np.float32)


def hybrid_colour(high_near: np.ndarray, low_near: np.ndarray, low_far: np.ndarray, mode: str) -> np.ndarray:
    """``l(S) + g h(G)`` (un-premultiplied, float32) for detail ``mode``."""
    return (low_far + detail_gain(low_far, low_near, mode) * high_near).astype(np.float32)
