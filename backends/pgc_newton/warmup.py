"""``python -m pgc_newton.warmup``: compile the Warp kernels newton-vbd uses into Warp's kernel cache (about 2
minutes on 2 cores, once per installation), so the first simulation does not pay for it."""

from __future__ import annotations

import numpy as np

from pgc.types import BodyMotion, Mesh


def warm_up() -> None:
    """Two frames of a 2-triangle cloth over a 2-triangle body: every kernel of a simulation is loaded."""
    from pgc_newton.cloth import NewtonVBDSimulator

    square = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.0, 0.1], [0.0, 0.0, 0.1]])
    faces = np.array([[0, 2, 1], [0, 3, 2]])
    cloth = Mesh(square + [0.0, 1.0, 0.0], faces, name="warmup")
    body = BodyMotion(np.repeat((square * 3.0)[None], 3, axis=0), faces, name="warmup")
    NewtonVBDSimulator({"settle_frames": 0, "substeps": 2, "iterations": 1}).simulate(cloth, body)


if __name__ == "__main__":
    warm_up()
