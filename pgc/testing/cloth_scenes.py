"""Small analytic scenes for tests and benchmarks: a square cloth, a skirt, a sphere and a box body."""

from __future__ import annotations

import numpy as np

from pgc.types import BodyMotion, Mesh

QUICK_ANIMATE_CONFIG = """
[simulator]
use = ["xpbd-native", "xpbd-jax", "xpbd-torch"]
[simulator.xpbd-native]
substeps = 10
iterations = 10
settle_frames = 3
[simulator.xpbd-jax]
substeps = 10
iterations = 10
settle_frames = 3
[simulator.xpbd-torch]
substeps = 10
iterations = 10
settle_frames = 3
[stages.animate]
seconds = 0.4
"""
"""A run configuration for animate tests: each XPBD simulator at 10 substeps x 10 iterations, 3 settle frames,
0.4 s of motion."""


def grid_cloth(n: int, size: float = 1.0, height: float = 0.0, vertical: bool = False) -> Mesh:
    """An n x n vertex square of side ``size`` (m), horizontal at y = ``height`` (or vertical in the xy plane,
    top edge at y = ``height``), alternating diagonals. Vertex (r, c) has index r * n + c."""
    s = np.linspace(-size / 2, size / 2, n)
    a, b = np.meshgrid(s, s, indexing="ij")
    if vertical:
        v = np.stack([b, height - (a + size / 2), np.zeros_like(a)], -1).reshape(-1, 3)
    else:
        v = np.stack([b, np.full_like(a, height), a], -1).reshape(-1, 3)
    faces = []
    for r in range(n - 1):
        for c in range(n - 1):
            i = r * n + c
            if (r + c) % 2:
                faces += [[i, i + n, i + 1], [i + 1, i + n, i + n + 1]]
            else:
                faces += [[i, i + n, i + n + 1], [i, i + n + 1, i + 1]]
    return Mesh(v, np.array(faces), name=f"grid{n}")


def uv_sphere(radius: float, center=(0.0, 0.0, 0.0), rings: int = 16, segments: int = 32) -> Mesh:
    """A closed UV sphere, faces counter-clockwise seen from outside."""
    verts = [[0.0, radius, 0.0]]
    for i in range(1, rings):
        th = np.pi * i / rings
        for j in range(segments):
            ph = 2 * np.pi * j / segments
            verts.append([radius * np.sin(th) * np.cos(ph), radius * np.cos(th), radius * np.sin(th) * np.sin(ph)])
    verts.append([0.0, -radius, 0.0])
    faces, bottom = [], len(verts) - 1

    def ring(i: int, j: int) -> int:
        return 1 + (i - 1) * segments + j % segments

    for j in range(segments):
        faces.append([0, ring(1, j + 1), ring(1, j)])
        faces.append([bottom, ring(rings - 1, j), ring(rings - 1, j + 1)])
    for i in range(1, rings - 1):
        for j in range(segments):
            a, b, c, d = ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1)
            faces += [[a, b, d], [a, d, c]]
    return Mesh(np.array(verts) + np.asarray(center), np.array(faces), name="sphere")


def skirt(body_radius: float, length: float, top: float, rows: int, segments: int, flare: float = 0.02) -> Mesh:
    """An open cylinder (tube) of ``rows`` x ``segments`` vertices around the y axis, hanging from
    y = ``top``, radius growing from ``body_radius`` + 1 cm by ``flare`` (m) towards the hem."""
    verts = []
    for i in range(rows):
        t = i / (rows - 1)
        r = body_radius + 0.01 + flare * t
        y = top - length * t
        for j in range(segments):
            ph = 2 * np.pi * j / segments
            verts.append([r * np.cos(ph), y, r * np.sin(ph)])
    faces = []
    for i in range(rows - 1):
        for j in range(segments):
            a, b = i * segments + j, i * segments + (j + 1) % segments
            c, d = a + segments, b + segments
            faces += [[a, c, b], [b, c, d]]
    return Mesh(np.array(verts), np.array(faces), name="skirt")


def static_motion(body: Mesh, frames: int, fps: float = 30.0) -> BodyMotion:
    return BodyMotion(np.repeat(body.vertices[None], frames, axis=0), body.faces, fps, f"{body.name}-static")


def moving_motion(body: Mesh, frames: int, velocity=(0.0, 0.0, 1.0), fps: float = 30.0) -> BodyMotion:
    """The body translating with constant ``velocity`` (m/s) after its first frame."""
    t = np.arange(frames)[:, None, None] / fps
    return BodyMotion(body.vertices[None] + t * np.asarray(velocity), body.faces, fps, f"{body.name}-moving")
