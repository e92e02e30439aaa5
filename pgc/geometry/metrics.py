"""Mesh quality and accuracy metrics (numpy/scipy).

Accuracy against a ground-truth mesh is measured from surface samples to the other surface: Chamfer distance (mean of the two
directional mean distances, and the 95th percentile of all distances), normal consistency (mean |n . n'|
of nearest samples, both directions), and F-score at thresholds (harmonic mean of precision and recall).
Ground truth may be restricted to what the cameras see (hidden surfaces such as the body under a garment
cannot be reconstructed from images). Distances in metres.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgc.geometry.labels import edge_components, face_adjacency
from pgc.geometry.raster import covered_pixels, rasterize
from pgc.types import Camera, Mesh


def sample_surface(mesh: Mesh, count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``count`` area-uniform surface points (N, 3) and the index of their face (N,)."""
    rng = np.random.default_rng(seed)
    area = mesh.face_areas()
    if area.sum() <= 0:
        raise ValueError("mesh has zero surface area")
    face = rng.choice(len(area), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    w = np.stack([1 - s, s * (1 - r2), s * r2], axis=1)
    return np.einsum("nk,nkj->nj", w, mesh.vertices[mesh.faces[face]]), face


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest points (N, 3) on triangles (a, b, c) to points ``p`` (all (N, 3)); Voronoi-region test
    (Ericson, Real-Time Collision Detection 5.1.5). Degenerate triangles give a point on their edges."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return _closest_point(p, a, b, c)


def _closest_point(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = va + vb + vc
    v_in, w_in = vb / denom, vc / denom
    t_ab = d1 / (d1 - d3)
    t_ac = d2 / (d2 - d6)
    t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    out = a + v_in[:, None] * ab + w_in[:, None] * ac
    cases = [  # later assignments take precedence, so the most specific regions come last
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + t_bc[:, None] * (c - b)),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + t_ac[:, None] * ac),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + t_ab[:, None] * ab),
        ((d6 >= 0) & (d5 <= d6), c),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d1 <= 0) & (d2 <= 0), a),
    ]
    for mask, value in cases:
        out = np.where(mask[:, None], value, out)
    bad = ~np.all(np.isfinite(out), axis=1)  # a degenerate triangle that fell through: nearest vertex
    if bad.any():
        verts = np.stack([a[bad], b[bad], c[bad]], 1)
        k = np.argmin(np.linalg.norm(verts - p[bad, None], axis=2), axis=1)
        out[bad] = verts[np.arange(len(k)), k]
    return out


def point_mesh_distance(points: np.ndarray, mesh: Mesh, candidates: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Distance (N,) from each point to the surface of ``mesh`` and the index of the closest face (N,).

    Exact among the ``candidates`` faces whose centroids are nearest (exact for meshes whose triangles
    are not much longer than the distances measured)."""
    from scipy.spatial import cKDTree

    tri = mesh.vertices[mesh.faces]
    k = min(candidates, len(tri))
    _, idx = cKDTree(tri.mean(1)).query(points, k=k, workers=-1)
    idx = idx.reshape(len(points), k)
    best = np.full(len(points), np.inf)
    face = np.zeros(len(points), np.int64)
    for j in range(k):
        t = tri[idx[:, j]]
        d = np.linalg.norm(closest_point_on_triangles(points, t[:, 0], t[:, 1], t[:, 2]) - points, axis=1)
        better = d < best
        best[better], face[better] = d[better], idx[better, j]
    return best, face


def visible_faces(mesh: Mesh, cameras: list[Camera], min_views: int = 1) -> np.ndarray:
    """(F,) bool: faces that cover at least one pixel centre in ``min_views`` or more cameras (2: the
    surface that multi-view reconstruction can see; 1 includes glimpses through openings)."""
    count = np.zeros(len(mesh.faces), dtype=np.int64)
    for cam in cameras:
        fid = rasterize(cam, mesh.vertices, mesh.faces).face_id
        count[np.unique(fid[fid >= 0])] += 1
    return count >= min_views


def compare_meshes(pred: Mesh, gt: Mesh, samples: int = 100_000, thresholds: tuple[float, ...] = (0.005, 0.01),
                   gt_faces: np.ndarray | None = None, seed: int = 0) -> dict[str, float]:
    """Chamfer (mean, p95), normal consistency and F-scores of ``pred`` against ``gt`` (metres).

    Distances go from area-uniform samples of one mesh to the other's surface (exact point-triangle
    distances, so the figures do not depend on a sampling density of both sides).

    ``gt_faces``: optional (F_gt,) bool restricting the ground truth (e.g. :func:`visible_faces`).
    Keys: chamfer_mean, chamfer_p95, accuracy_mean (pred->gt), completeness_mean (gt->pred),
    normal_consistency, fscore_<mm>mm, precision_<mm>mm, recall_<mm>mm.
    """
    if gt_faces is not None:
        gt = gt.submesh(gt_faces)[0]
    p, pf = sample_surface(pred, samples, seed)
    g, gf = sample_surface(gt, samples, seed + 1)
    d_pg, f_pg = point_mesh_distance(p, gt)
    d_gp, f_gp = point_mesh_distance(g, pred)
    pn_all, gn_all = pred.face_normals(), gt.face_normals()
    out = {
        "chamfer_mean": float(0.5 * (d_pg.mean() + d_gp.mean())),
        "chamfer_p95": float(np.percentile(np.concatenate([d_pg, d_gp]), 95)),
        "accuracy_mean": float(d_pg.mean()),
        "completeness_mean": float(d_gp.mean()),
        "normal_consistency": float(0.5 * (np.abs(np.einsum("ij,ij->i", pn_all[pf], gn_all[f_pg])).mean()
                                           + np.abs(np.einsum("ij,ij->i", gn_all[gf], pn_all[f_gp])).mean())),
    }
    for t in thresholds:
        tag = f"{t * 1000:g}mm"
        precision, recall = float((d_pg < t).mean()), float((d_gp < t).mean())
        out[f"precision_{tag}"], out[f"recall_{tag}"] = precision, recall
        out[f"fscore_{tag}"] = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    return out


def transfer_labels(src: Mesh, dst: Mesh, samples: int = 200_000, seed: int = 0) -> np.ndarray:
    """Labels of ``src`` faces carried to ``dst`` faces: the label of the nearest ``src`` surface sample
    to each ``dst`` face centroid."""
    from scipy.spatial import cKDTree

    p, f = sample_surface(src, samples, seed)
    _, idx = cKDTree(p).query(dst.vertices[dst.faces].mean(1), workers=-1)
    return src.face_labels[f[idx]]


def label_iou(pred: Mesh, gt: Mesh, label_ids: list[int]) -> float:
    """Area-weighted IoU of the faces whose label is in ``label_ids`` (e.g. the garment ids), measured on
    ``pred``'s faces with the ground-truth label of the nearest ``gt`` surface point."""
    truth = np.isin(transfer_labels(gt, pred), label_ids)
    guess = np.isin(pred.face_labels, label_ids)
    area = pred.face_areas()
    union = area[truth | guess].sum()
    return float(area[truth & guess].sum() / union) if union > 0 else 1.0


def triangle_angles_deg(mesh: Mesh) -> np.ndarray:
    """(F, 3) interior angles in degrees (0 for degenerate corners)."""
    v = mesh.vertices[mesh.faces]
    out = np.zeros((len(v), 3))
    for k in range(3):
        a = v[:, (k + 1) % 3] - v[:, k]
        b = v[:, (k + 2) % 3] - v[:, k]
        na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
        cos = np.divide(np.einsum("ij,ij->i", a, b), na * nb, out=np.ones(len(v)), where=(na * nb) > 0)
        out[:, k] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def topology_report(mesh: Mesh) -> dict[str, Any]:
    """Manifoldness and quality figures: non-manifold edges/vertices, boundary edges, orientation, components,
    minimum angle (degrees), degenerate faces (an angle under 1e-3 degrees or zero area)."""
    f = mesh.faces
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    und = np.sort(directed, axis=1)
    _, inverse, counts = np.unique(und, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    forward = (directed[:, 0] < directed[:, 1]).astype(np.int64)
    fwd_count = np.bincount(inverse, weights=forward, minlength=len(counts))
    interior = counts == 2
    misoriented = int(np.count_nonzero(interior & (fwd_count != 1)))
    angles = triangle_angles_deg(mesh)
    return {
        "vertices": int(len(mesh.vertices)),
        "faces": int(len(f)),
        "non_manifold_edges": int(np.count_nonzero(counts > 2)),
        "non_manifold_vertices": int(len(non_manifold_vertices(mesh.faces, len(mesh.vertices)))),
        "boundary_edges": int(np.count_nonzero(counts == 1)),
        "misoriented_edges": misoriented,
        "components": int(len(np.unique(edge_components(np.ones(len(f), bool), face_adjacency(f))))) if len(f) else 0,
        "min_angle_deg": float(angles.min()) if len(f) else 0.0,
        "degenerate_faces": int(np.count_nonzero((angles.min(1) < 1e-3) | (mesh.face_areas() <= 0))),
    }


def is_manifold(report: dict[str, Any]) -> bool:
    return report["non_manifold_edges"] == 0 and report["non_manifold_vertices"] == 0 and report["misoriented_edges"] == 0


def non_manifold_vertices(faces: np.ndarray, num_vertices: int) -> np.ndarray:
    """Ids of vertices whose incident faces form more than one edge-connected fan (bow-ties)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return np.zeros(0, np.int64)
    corner_vertex = f.ravel()
    corner_face = np.repeat(np.arange(len(f)), 3)
    # Two corners at the same vertex are linked when their faces share an edge through that vertex.
    adj = face_adjacency(f)
    shared = (f[adj[:, 0]][:, :, None] == f[adj[:, 1]][:, None, :]).any(2)  # (P, 3) corners of a also in b
    pa = np.repeat(adj[:, 0], 3)[shared.ravel()]
    pb = np.repeat(adj[:, 1], 3)[shared.ravel()]
    pv = f[adj[:, 0]].ravel()[shared.ravel()]
    order = np.lexsort((corner_face, corner_vertex))
    sorted_key = (corner_vertex * len(f) + corner_face)[order]
    ia = order[np.searchsorted(sorted_key, pv * len(f) + pa)]
    ib = order[np.searchsorted(sorted_key, pv * len(f) + pb)]
    n = len(corner_vertex)
    g = coo_matrix((np.ones(len(ia)), (ia, ib)), shape=(n, n))
    _, comp = connected_components(g, directed=False)
    fans = np.unique(np.stack([corner_vertex, comp], axis=1), axis=0)
    per_vertex = np.bincount(fans[:, 0], minlength=num_vertices)
    return np.nonzero(per_vertex > 1)[0]


def uv_overlap(mesh: Mesh, resolution: int = 1024) -> dict[str, float]:
    """Overlap of the UV atlas: the fraction of covered texels (centres strictly inside a UV triangle) that
    more than one triangle covers, and the number of flipped (negative-area) UV triangles."""
    uv = mesh.uv[mesh.face_uv].astype(np.float64) * resolution  # (F, 3, 2), texel units
    uv[..., 1] = resolution - uv[..., 1]  # v up -> row down (flips orientation)
    signed = (uv[:, 1, 0] - uv[:, 0, 0]) * (uv[:, 2, 1] - uv[:, 0, 1]) - (uv[:, 2, 0] - uv[:, 0, 0]) * (uv[:, 1, 1] - uv[:, 0, 1])
    cover = np.zeros(resolution * resolution, dtype=np.int32)
    for _, pix, _ in covered_pixels(uv, resolution, resolution, eps=-1e-6):
        np.add.at(cover, pix, 1)
    covered = np.count_nonzero(cover)
    return {"overlap_fraction": float(np.count_nonzero(cover > 1) / max(covered, 1)),
            "flipped_faces": int(np.count_nonzero(signed > 0)), "texels_covered": int(covered)}
