"""Ground-truth frames kept across run folders, by content key: a fibre truth's frame costs about 18 s of CPU (the
default demo's 30 frames about 5.5 minutes on 2 cores), and the demo, the sweeps and the bench evaluate the same
scenes again in new folders. The truth is the grader, not the pipeline's work: keeping it is what the capture cache
(:mod:`pgc.pipeline.capture_cache`) does for the capture.

An entry is one frame, ``$PGC_CAPTURE_CACHE/frames/KEY.npz`` (the capture cache's folder; ``off`` turns both off),
written under a temporary name and renamed when complete. Its key covers everything the render reads: the bytes of
the capture's ``ground_truth/`` folder, the posed truth garment and body (their float64 bytes), the cameras, the light
at that frame, the sampling (samples a pass, noise target, most samples) and the seed, the scene renderer (implementation, options, version) and the source of the
generator and of the renderer's package. Frames with equal keys are equal (Mitsuba's LLVM rendering is deterministic
for a fixed seed), so frame 0 of every motion (the capture pose) is rendered once.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pgc.io.light_record import rotation_at
from pgc.pipeline.cache import array_key, content_key, file_key
from pgc.pipeline.capture_cache import capture_cache_root, source_key
from pgc.types import Camera


def frame_cache_root() -> Path | None:
    """``frames/`` in the capture cache's folder; None when that cache is off."""
    root = capture_cache_root()
    return None if root is None else root / "frames"


def light_at(record: dict[str, Any], frame: int) -> dict[str, Any]:
    """What decides the light of one frame: the kind; for an environment map its sha256 and rotation (degrees)."""
    if record.get("kind") != "envmap":
        return {"kind": record.get("kind")}
    return {"kind": "envmap", "sha256": record.get("sha256"), "rotation_deg": round(rotation_at(record, frame), 9)}


def camera_identity(camera: Camera) -> list[Any]:
    """A camera's name, size and its intrinsics and extrinsics (as written to JSON)."""
    return [camera.name, camera.width, camera.height, np.asarray(camera.K).tolist(), np.asarray(camera.R).tolist(),
            np.asarray(camera.t).tolist()]


@dataclass(frozen=True)
class TruthFrameCache:
    """The cached frames of one truth scene rendered by one scene renderer; ``root`` None: nothing is kept."""

    root: Path | None
    scene: str
    """Key of the truth scene, the renderer and the sampling settings shared by every frame."""

    @classmethod
    def open(cls, capture_dir: Path, renderer_key: Any, renderer_class: type, sampling: str, gt_samples: int,
             sampler: str) -> TruthFrameCache:
        """The cache of the truth of ``capture_dir`` rendered by the renderer of ``renderer_key`` (its
        implementation, options and version) and ``renderer_class`` (whose package's source the key covers), sampled
        as ``sampling`` says (:func:`pgc.synth.frames.sampling_tag`)."""
        root = frame_cache_root()
        if root is None:
            return cls(None, "")
        truth = file_key(Path(capture_dir) / "ground_truth")
        return cls(root, content_key("truth-frame", truth, renderer_key, source_key(renderer_class), sampling,
                                     gt_samples, sampler))

    def key(self, garment: np.ndarray, body: np.ndarray, cameras: list[Camera], light: dict[str, Any],
            seed: int) -> str:
        """The key of one frame: posed truth garment and body (metres), cameras, the frame's light, render seed."""
        return content_key(self.scene, array_key(np.asarray(garment, np.float64)), array_key(np.asarray(body, np.float64)),
                           [camera_identity(c) for c in cameras], light, seed)

    def load(self, key: str) -> dict[str, np.ndarray] | None:
        """The frame of ``key``, or None when it is not kept (or the cache is off)."""
        if self.root is None or not (self.root / f"{key}.npz").is_file():
            return None
        with np.load(self.root / f"{key}.npz") as z:
            return {name: z[name] for name in z.files}

    def store(self, key: str, frame: dict[str, np.ndarray]) -> None:
        """Keep ``frame`` under ``key`` (written whole under a temporary name, then renamed)."""
        if self.root is None:
            return
        self.root.mkdir(parents=True, exist_ok=True)
        partial = self.root / f".{key}.{os.getpid()}.partial.npz"
        np.savez(partial, **frame)
        os.replace(partial, self.root / f"{key}.npz")
