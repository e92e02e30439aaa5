"""How the near field's detail enters the hybrid: ``I = l(S) + g * h(G)`` with a per-pixel, per-channel gain g
(``residual`` adds the far field's own high band).

- ``additive`` (the paper): ``g = 1``, so ``I = h(G) + l(S)``. The detail keeps the amplitude it had under the
  capture light, whatever light the far field is rendered under.
- ``multiplicative``: ``g = l(S) / l(G)``, so ``I = l(S) * G / l(G)``: the near field's detail is a ratio to
  its own low band, and it follows the far field's shading (a light twice as bright on the far field doubles
  the detail). The denominator is guarded: ``g = min(l(S) / max(l(G), GAIN_FLOOR), MAX_GAIN)``, finite
  everywhere (``l(G) = 0`` where the Gaussians do not cover, a black near field), exact where ``l(G) >=
  GAIN_FLOOR`` and the ratio is below ``MAX_GAIN``.
- ``ratio``: ``g = l(S) / l(S_c)``, with ``S_c`` the far field under the capture light: the detail keeps its
  amplitude and is scaled by the change of the far field's shading from the capture light to the render light
  (guarded as ``multiplicative``). Under the capture light ``S_c = S`` and it is ``additive``; under another light
  it costs a second far-field render.
- ``residual``: ``I = S + l(S) (h(G) / l(G) - h(S_c) / l(S_c))`` (both ratios guarded as above): the far field
  whole, its own high band included (texture and shading detail that a novel light changes, rendered under
  that light), plus the near field's relative detail beyond the far field's relative detail under the capture
  light. Under the capture light it is ``multiplicative``; where the near field equals the far field under the
  capture light it is the far field ``S`` under any light. Same cost as ``ratio``.
All modes give ``I = G`` where ``l(S) = l(G)`` (the far field matches the near field's low band, as at the
capture pose under the capture light). Arrays are un-premultiplied linear RGB (H, W, 3); numpy only.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

DetailMode = Literal["additive", "multiplicative", "ratio", "residual"]
DETAIL_MODES: tuple[str, ...] = ("additive", "multiplicative", "ratio", "residual")
SINGLE_GAIN_MODES: tuple[str, ...] = ("additive", "multiplicative", "ratio")
"""The modes whose hybrid is ``l(S) + g h(G)`` (:func:`detail_gain`)."""
CAPTURE_FAR_FIELD_MODES: tuple[str, ...] = ("ratio", "residual")
"""The modes that read the far field under the capture light ``S_c`` (a second far-field render under a novel
light)."""
GAIN_FLOOR = 1e-3
"""Smallest low band (linear radiance) a gain divides by."""
MAX_GAIN = 16.0
"""Largest multiplicative gain (a far field 16 x brighter than the near field's low band)."""


def guarded_ratio(numerator: np.ndarray, denominator: np.ndarray) -> np.ndarray:
    """``min(max(numerator, 0) / max(denominator, GAIN_FLOOR), MAX_GAIN)``, float32: finite for any finite input."""
    numerator = np.maximum(np.asarray(numerator, np.float32), 0.0)
    denominator = np.maximum(np.asarray(denominator, np.float32), GAIN_FLOOR)
    return np.minimum(numerator / denominator, MAX_GAIN).astype(np.float32)


def detail_gain(low_far: np.ndarray, low_near: np.ndarray, mode: str,
                low_far_capture: np.ndarray | None = None) -> np.ndarray | float:
    """The gain g of the near field's high band ``h(G)`` in ``l(S) + g h(G)`` (module docstring): 1 for
    ``additive``, the guarded ``l(S) / l(G)`` for ``multiplicative``, the guarded ``l(S) / l(S_c)`` for ``ratio``
    (``low_far_capture`` None: the render light is the capture light, g = 1). ``residual`` has two gains
    (:func:`hybrid_colour`)."""
    if mode not in SINGLE_GAIN_MODES:
        raise ValueError(f"detail mode must be one of {SINGLE_GAIN_MODES} for a gain, not {mode!r}")
    if mode == "additive" or (mode == "ratio" and low_far_capture is None):
        return 1.0
    return guarded_ratio(low_far, low_near if mode == "multiplicative" else low_far_capture)


def hybrid_colour(high_near: np.ndarray, low_near: np.ndarray, low_far: np.ndarray, mode: str,
                  low_far_capture: np.ndarray | None = None, high_far: np.ndarray | None = None,
                  high_far_capture: np.ndarray | None = None) -> np.ndarray:
    """``l(S) + g h(G)`` (un-premultiplied, float32) for detail ``mode`` (:func:`detail_gain`); for ``residual``
    ``l(S) + h(S) + g_m h(G) - g_r h(S_c)`` with the gains of ``multiplicative`` and ``ratio``, which needs
    ``high_far`` = h(S) and, under a novel light, ``low_far_capture`` and ``high_far_capture`` = l(S_c), h(S_c)
    (None: the render light is the capture light, S_c = S, and it is ``multiplicative``)."""
    if mode != "residual":
        return (low_far + detail_gain(low_far, low_near, mode, low_far_capture) * high_near).astype(np.float32)
    near_gain = detail_gain(low_far, low_near, "multiplicative")
    if high_far_capture is None:
        return (low_far + near_gain * high_near).astype(np.float32)
    if high_far is None or low_far_capture is None:
        raise ValueError("detail mode 'residual' under a novel light needs h(S) and l(S_c) beside h(S_c)")
    far_gain = detail_gain(low_far, low_near, "ratio", low_far_capture)
    return (low_far + high_far + near_gain * high_near - far_gain * high_far_capture).astype(np.float32)
