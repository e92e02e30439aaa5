"""Stage ``body_fit``: the body model's shape and capture pose fitted to the capture's silhouettes, segmentation
labels and (where present) 2D keypoints (:func:`pgc.body.fit.fit_body`); ``pgc reconstruct`` runs it for a
capture without a ground-truth body, or with ``motion_body = "fit"`` for any capture, and ``pgc body fit`` runs the
same fit alone."""

from __future__ import annotations

from typing import Literal, get_args

from pydantic import Field

from pgc.options import Options, count
from pgc.stages.declaration import Stage

MotionBody = Literal["truth", "fit"]
MOTION_BODIES: tuple[str, ...] = get_args(MotionBody)
"""The bodies an asset's garment can move on in ``pgc animate`` (``motion_body``; ``pgc reconstruct --body``)."""


class BodyFitSettings(Options):
    """The body fit (:func:`pgc.body.fit.fit_body`; the method and its measured accuracy: docs/body.md)."""

    views: int = count(12, 1, 4096, "views the fit uses, chosen far apart over the capture (all when it has fewer)")
    iterations: int = count(300, 10, 100_000, "most Adam steps over the three coarse-to-fine phases")
    keypoints: bool = Field(True, description="use the capture's 2D keypoints (keypoints/<view>.json) when it has "
                                              "them")
    tolerance: float = Field(5e-4, ge=0.0, le=1.0, description="the last phase also stops when the loss fell by less "
                                                               "than this fraction over its last 20 steps")
    learning_rate: float = Field(0.05, gt=0.0, le=1.0, description="Adam's step size (radians, metres/10 and "
                                                                   "shape logits), decayed in the last phase")
    pose_prior: float = Field(2.0, ge=0.0, le=1e6, description="weight of the squared joint angles (rad^2) "
                                                               "against the silhouette loss (px^2 per pixel)")
    motion_body: MotionBody = Field("truth", description=(
        "the body the asset's garment moves on in 'pgc animate': 'truth' = a synthetic capture's true body, 'fit' "
        "= the body fitted to the capture (this stage, run even when the capture has a true body), as the paper "
        "measured; a capture without a true body always moves on its fitted body (pgc reconstruct --body)"))


STAGE = Stage(name="body_fit", command="reconstruct", version="3", inputs=("capture",),
              outputs=("body.json", "body.ply"), folder="ASSET/stages/body_fit", role="body_model",
              settings=BodyFitSettings, events=("body_fit",))
