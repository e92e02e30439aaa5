"""Initial mesh-embedded Gaussians (docs/method.md, section 2): uniform triangle point picking."""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError
from pgc.splats.binding import unbind_points
from pgc.splats.sh import num_sh_coeffs, rgb_to_sh_dc
from pgc.types import GaussianSet, Mesh, View

INIT_OPACITY = 0.1
INIT_COLOR_RANGE = (0.5, 0.7)


def sample_on_mesh(mesh: Mesh, count: int, rng: np.random.Generator, sh_degree: int = 3,
                   face_mask: np.ndarray | None = None) -> GaussianSet:
    """``count`` Gaussians uniformly distributed over the area of ``mesh`` (optionally only faces in
    ``face_mask``): identity local rotation, unit local scale (log 0), opacity 0.1, DC colour from
    U(0.5, 0.7)^3, higher SH zero (``(sh_degree+1)^2`` coefficients).
    """
    if count <= 0:
        raise PGCDataError(f"sample_on_mesh: count must be positive, got {count}")
    area = mesh.face_areas()
    if face_mask is not None:
        area = np.where(np.asarray(face_mask, bool), area, 0.0)
    total = area.sum()
    if not total > 0:
        raise PGCDataError(f"mesh '{mesh.name}': no triangle with positive area to place Gaussians on")
    parent = rng.choice(len(area), size=count, p=area / total)
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1.0
    u, v = np.where(flip, 1.0 - u, u), np.where(flip, 1.0 - v, v)
    tri = mesh.vertices[mesh.faces[parent]]
    points = tri[:, 0] + u[:, None] * (tri[:, 1] - tri[:, 0]) + v[:, None] * (tri[:, 2] - tri[:, 0])
    sh = np.zeros((count, num_sh_coeffs(sh_degree), 3))
    sh[:, 0] = rgb_to_sh_dc(rng.uniform(*INIT_COLOR_RANGE, size=(count, 3)))
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (count, 1))
    logit = np.log(INIT_OPACITY / (1.0 - INIT_OPACITY))
    return GaussianSet(parent=parent, means=unbind_points(points, parent, mesh.vertices, mesh.faces),
                       quats=quats, log_scales=np.zeros((count, 3)), opacity_logits=np.full(count, logit), sh=sh)


def colors_from_views(gaussians: GaussianSet, mesh: Mesh, views: list[View]) -> GaussianSet:
    """``gaussians`` with their DC colour set to the per-channel median, over the ``views`` that see it (z-buffer
    of ``mesh``), of the image at its centre: the fit then starts from the captured radiance instead of grey
    noise. Gaussians no view sees keep their colour."""
    from pgc.splats.binding import bind
    from pgc.texture.sample import sample_bilinear
    from pgc.texture.visibility import render_faces, visible_points

    points = bind(gaussians, mesh.vertices, mesh.faces).means
    samples = np.full((len(views), len(points), 3), np.nan)
    for i, view in enumerate(views):
        seen, xy = visible_points(points, gaussians.parent, render_faces(mesh, view.camera), view.camera)
        samples[i, seen] = sample_bilinear(view.image, xy[seen])
    seen_any = np.any(np.isfinite(samples[..., 0]), axis=0)
    sh = gaussians.sh.copy()
    if seen_any.any():
        sh[seen_any, 0] = rgb_to_sh_dc(np.nanmedian(samples[:, seen_any], axis=0))
    return GaussianSet(gaussians.parent, gaussians.means, gaussians.quats, gaussians.log_scales,
                       gaussians.opacity_logits, sh)
