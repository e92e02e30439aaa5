"""XPBD cloth maths written once for numpy, torch and JAX.

The functions take the :class:`pgc.arrays.ArrayOps` of an array library and are pure: they return new
arrays. The torch backend runs them eagerly, the JAX backend jits them (``ops.loop`` becomes
``lax.fori_loop``), numpy uses them for measurements.

Conventions: positions (V, 3) in metres; a constraint group is the tuple ``(ci, cj, rest, alpha_t, share)``
(vertex indices, rest lengths, compliance / h^2, and the factor applied to each multiplier update: 1 for a
graph colour, ``omega / max(n_i, n_j)`` for a Jacobi sweep); multipliers ``lam`` are one array per group.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

from pgc.arrays import ArrayOps

EPS = 1e-9
"""Lengths (m) below this have no direction: such constraints and contacts are skipped."""


def unit(ops: ArrayOps, v: Any) -> Any:
    """Normalised rows; zero rows stay zero."""
    n = ops.norm(v)
    return v / ops.xp.where(n > EPS, n, 1.0)[..., None]


class DistanceWeights(NamedTuple):
    """What :func:`project_distance` needs of a constraint group's masses and compliance, fixed during a run."""

    wi: Any
    """(C, 1) inverse mass of each constraint's vertex i."""
    wj_neg: Any
    """(C, 1) minus the inverse mass of vertex j."""
    movable: Any
    """(C,) ``w_i + w_j + alpha_t > 0``: False for two pinned vertices with zero compliance."""
    denom: Any
    """(C,) ``w_i + w_j + alpha_t``, 1 where not ``movable``."""


def distance_weights(ops: ArrayOps, inv_mass: Any, group: tuple) -> DistanceWeights:
    """The :class:`DistanceWeights` of ``group``: computed once per frame, not in every sweep."""
    ci, cj, _, alpha_t, _ = group
    wi, wj = inv_mass[ci], inv_mass[cj]
    denom = wi + wj + alpha_t
    movable = denom > 0
    return DistanceWeights(wi[:, None], -wj[:, None], movable, ops.xp.where(movable, denom, 1.0))


def project_distance(ops: ArrayOps, p: Any, weights: DistanceWeights, group: tuple, lam: Any) -> tuple[Any, Any]:
    """One XPBD update of a group of distance constraints ``C = |p_i - p_j| - L``.

    ``dlam = share * (-C - alpha_t lam) / (w_i + w_j + alpha_t)``; ``p_i += w_i dlam n``,
    ``p_j -= w_j dlam n`` with ``n`` the unit direction i - j. Constraints of zero length (no direction) or
    between two pinned vertices with zero compliance are left unchanged. ``weights``: the group's
    :func:`distance_weights`.
    """
    xp = ops.xp
    ci, cj, rest, alpha_t, share = group
    d = p[ci] - p[cj]
    length = ops.norm(d)
    good = (length > EPS) & weights.movable
    n = d / xp.where(good, length, 1.0)[:, None]
    dlam = xp.where(good, (rest - length - alpha_t * lam) / weights.denom, 0.0) * share
    corr = dlam[:, None] * n
    p = ops.index_add(p, ci, weights.wi * corr)
    p = ops.index_add(p, cj, weights.wj_neg * corr)
    return p, lam + dlam


def constraint_residual(ops: ArrayOps, p: Any, group: tuple, lam: Any) -> tuple[Any, Any]:
    """Per-constraint XPBD residual ``C + alpha_t lam`` (m) and constraint value ``C`` (m)."""
    ci, cj, rest, alpha_t, _ = group
    c = ops.norm(p[ci] - p[cj]) - rest
    return c + alpha_t * lam, c


def closest_barycentric(ops: ArrayOps, p: Any, a: Any, b: Any, c: Any) -> tuple[Any, Any, Any]:
    """Barycentrics (u, v, w) of the point of triangle abc closest to p (Ericson's region tests).

    Arrays broadcast over leading dimensions. Degenerate triangles (zero area, repeated corners) resolve
    to a vertex or an edge; every division is guarded, so results are finite.
    """
    xp = ops.xp

    def dot(x: Any, y: Any) -> Any:
        return (x * y).sum(-1)

    def div(x: Any, y: Any) -> Any:
        ok = xp.abs(y) > 1e-30
        return xp.where(ok, x / xp.where(ok, y, 1.0), 0.0)

    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp = p - b
    d3, d4 = dot(ab, bp), dot(ac, bp)
    cp = p - c
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    total = va + vb + vc
    # interior
    v = div(vb, total)
    w = div(vc, total)
    zero, one = xp.zeros_like(v), xp.ones_like(v)
    # regions in reverse priority: each later assignment wins (Ericson returns at the first match)
    t_bc = div(d4 - d3, (d4 - d3) + (d5 - d6))
    m = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    v, w = xp.where(m, 1 - t_bc, v), xp.where(m, t_bc, w)
    t_ac = div(d2, d2 - d6)
    m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    v, w = xp.where(m, zero, v), xp.where(m, t_ac, w)
    m = (d6 >= 0) & (d5 <= d6)
    v, w = xp.where(m, zero, v), xp.where(m, one, w)
    t_ab = div(d1, d1 - d3)
    m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    v, w = xp.where(m, t_ab, v), xp.where(m, zero, w)
    m = (d3 >= 0) & (d4 <= d3)
    v, w = xp.where(m, one, v), xp.where(m, zero, w)
    m = (d1 <= 0) & (d2 <= 0)
    v, w = xp.where(m, zero, v), xp.where(m, zero, w)
    return 1 - v - w, v, w


class Contact(NamedTuple):
    """The closest body point of each cloth vertex among its candidate triangles."""

    tri: Any
    """(V, 3) body vertex indices of the chosen triangle."""
    bary: Any
    """(V, 3) barycentrics of the closest point."""
    point: Any
    """(V, 3) the closest point (m)."""
    normal: Any
    """(V, 3) unit normal there (barycentric blend of body vertex normals)."""
    signed: Any
    """(V,) signed distance along the normal (m); negative inside the body."""


def closest_contact(ops: ArrayOps, p: Any, body: Any, normals: Any, corners: Any) -> Contact:
    """Closest point of ``p`` (V, 3) on the candidate triangles ``corners`` (V, K, 3) of ``body`` (B, 3)."""
    xp = ops.xp
    a, b, c = body[corners[..., 0]], body[corners[..., 1]], body[corners[..., 2]]
    u, v, w = closest_barycentric(ops, p[:, None, :], a, b, c)
    q = u[..., None] * a + v[..., None] * b + w[..., None] * c
    dist2 = ((p[:, None, :] - q) ** 2).sum(-1)
    rows = xp.arange(p.shape[0])
    k = dist2.argmin(1)
    tri = corners[rows, k]
    bary = xp.stack([u[rows, k], v[rows, k], w[rows, k]], -1)
    point = q[rows, k]
    n = unit(ops, (bary[..., None] * normals[tri]).sum(-2))
    return Contact(tri, bary, point, n, ((p - point) * n).sum(-1))


def push_out(ops: ArrayOps, p: Any, point: Any, normal: Any, active: Any, offset: float) -> tuple[Any, Any]:
    """Project ``active`` vertices onto the half-space ``(p - point) . normal >= offset``; returns the new
    positions and the (V,) push depths (m)."""
    depth = ops.xp.where(active, offset - ((p - point) * normal).sum(-1), 0.0).clip(min=0.0)
    return p + depth[:, None] * normal, depth


def contact_mask(ops: ArrayOps, p: Any, con: Contact, radius: float, free: Any) -> Any:
    """Vertices that collide: free and within ``radius`` of the body surface (far from the surface the side
    test of a candidate triangle is unreliable: the wrong side of a thin limb, an open body)."""
    return (free > 0) & (ops.norm(p - con.point) < radius)


def collide_body(ops: ArrayOps, p: Any, x_start: Any, body: Any, body_start: Any, normals: Any, corners: Any,
                 offset: float, friction: float, radius: float, free: Any, pushed: Any) -> Any:
    """Push vertices closer than ``offset`` to the body out along the body normal, with Coulomb friction.

    Friction acts on the tangential displacement relative to the body point over the substep
    (``x_start`` -> ``p`` against ``body_start`` -> ``body``): removed up to ``friction * depth``, with
    depth the normal correction of this push plus ``pushed`` (V,), the contact correction already applied
    during the iterations. ``free``: (V,) 1 for simulated vertices, 0 for pinned ones.
    """
    xp = ops.xp
    con = closest_contact(ops, p, body, normals, corners)
    p, depth = push_out(ops, p, con.point, con.normal, contact_mask(ops, p, con, radius, free), offset)
    depth = depth + pushed
    hit = depth > 0
    body_move = con.point - (con.bary[..., None] * body_start[con.tri]).sum(-2)
    rel = (p - x_start) - body_move
    tang = rel - (rel * con.normal).sum(-1)[:, None] * con.normal
    tl = ops.norm(tang)
    scale = xp.where(hit & (tl > EPS), (friction * depth / xp.where(tl > EPS, tl, 1.0)).clip(max=1.0), 0.0)
    return p - scale[:, None] * tang


def separate_pairs(ops: ArrayOps, p: Any, inv_mass: Any, pi: Any, pj: Any, valid: Any, thickness: float) -> Any:
    """Self-collision: push apart vertex pairs closer than ``thickness`` (Jacobi, averaged per vertex)."""
    xp = ops.xp
    d = p[pi] - p[pj]
    length = ops.norm(d)
    wi, wj = inv_mass[pi], inv_mass[pj]
    active = valid & (length < thickness) & (length > EPS) & (wi + wj > 0)
    n = d / xp.where(active, length, 1.0)[:, None]
    mag = xp.where(active, (thickness - length) / xp.where(active, wi + wj, 1.0), 0.0)
    count = ops.index_add(ops.index_add(xp.zeros_like(inv_mass), pi, active * 1.0), pj, active * 1.0)
    scale = 1.0 / xp.where(count > 0, count, 1.0)
    corr = mag[:, None] * n
    p = ops.index_add(p, pi, (wi * scale[pi])[:, None] * corr)
    return ops.index_add(p, pj, -(wj * scale[pj])[:, None] * corr)


class Statics(NamedTuple):
    """Arrays that stay fixed during a run (one backend's arrays)."""

    inv_mass: Any
    free: Any
    groups: tuple
    """Constraint groups, see the module docstring."""
    gravity: Any


class FrameInput(NamedTuple):
    """What changes every frame: the body at both ends of the frame and the candidate triangles."""

    body0: Any
    body1: Any
    normals0: Any
    normals1: Any
    corners: Any
    """(V, K, 3) body vertex indices of each cloth vertex's candidate triangles."""
    pairs: Any
    """(P, 2) self-collision vertex pairs (padded)."""
    pair_valid: Any
    """(P,) bool, False on padding."""


@dataclass(frozen=True)
class StepSettings:
    """Scalars of a run (traced under JIT, except ``self_collision``: one program serves every value)."""

    substeps: int
    iterations: int
    h: float
    """Substep length (s)."""
    damping: float
    """Velocity factor per substep."""
    offset: float
    friction: float
    contact_radius: float
    max_step: float
    """Largest displacement of a vertex in one substep before constraints (m): half the contact radius."""
    self_collision: bool
    thickness: float


def advance_frame(ops: ArrayOps, s: StepSettings, statics: Statics, x: Any, v: Any, frame: FrameInput,
                  ) -> tuple[Any, Any, Any, Any]:
    """Simulate one frame: ``s.substeps`` XPBD substeps, the body interpolated linearly inside the frame.

    Per substep: damping and gravity, prediction (displacement clamped to ``s.max_step``), multipliers
    reset, contact planes from the closest body points, ``s.iterations`` sweeps over the constraint groups
    and the contact planes, self-collision (optional), body collision with friction on fresh closest
    points, velocity update. Returns positions,
    velocities, and the final substep's residuals ``C + alpha_t lam`` and values ``C`` (concatenated over
    groups).
    """
    xp = ops.xp
    lam0 = tuple(xp.zeros_like(g[2]) for g in statics.groups)
    weights = tuple(distance_weights(ops, statics.inv_mass, g) for g in statics.groups)

    def substep(k: Any, carry: tuple) -> tuple:
        x, v, _ = carry
        t0, t1 = k / s.substeps, (k + 1) / s.substeps
        body_start = frame.body0 + t0 * (frame.body1 - frame.body0)
        body = frame.body0 + t1 * (frame.body1 - frame.body0)
        normals = unit(ops, frame.normals0 + t1 * (frame.normals1 - frame.normals0))
        v = v * s.damping + (s.h * statics.free)[:, None] * statics.gravity
        step = s.h * v
        length = ops.norm(step)
        # no vertex moves more than half the contact radius per substep: nothing tunnels through the body
        p = x + step * (s.max_step / xp.where(length > s.max_step, length, s.max_step))[:, None]

        con = closest_contact(ops, p, body, normals, frame.corners)  # contact planes for the iterations
        active = contact_mask(ops, p, con, s.contact_radius, statics.free)
        pushed = xp.where(active, s.offset - con.signed, 0.0).clip(min=0.0)  # normal correction, for friction

        def sweep(_: Any, state: tuple) -> tuple:
            p, lam = state
            out = []
            for g, w, lg in zip(statics.groups, weights, lam):
                p, lg = project_distance(ops, p, w, g, lg)
                out.append(lg)
            p, _ = push_out(ops, p, con.point, con.normal, active, s.offset)
            return p, tuple(out)

        p, lam = ops.loop(s.iterations, sweep, (p, lam0))
        if s.self_collision:
            p = separate_pairs(ops, p, statics.inv_mass, frame.pairs[:, 0], frame.pairs[:, 1], frame.pair_valid,
                               s.thickness)
        p = collide_body(ops, p, x, body, body_start, normals, frame.corners, s.offset, s.friction,
                         s.contact_radius, statics.free, pushed)
        return p, (p - x) / s.h, lam

    x, v, lam = ops.loop(s.substeps, substep, (x, v, lam0))
    res = [constraint_residual(ops, x, g, lg) for g, lg in zip(statics.groups, lam)]
    return x, v, res
