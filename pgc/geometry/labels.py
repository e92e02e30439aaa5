"""Per-face garment labels by visibility-aware multi-view voting of the view segmentations.

For every view, each face sample (centroid) that projects into the image, faces the camera and passes the
depth test against the mesh's own z-buffer casts a vote for the segmentation label under it, weighted by the
cosine between the face normal and the viewing ray; pixels on a label boundary vote with weight 0.1
(segmentations bleed there). Background votes are ignored.

A face's evidence is the sum of the cosines of the views that see it on the person, whatever the pixel's label; a
face is unobserved when its evidence is under 5 % of the median face's (a share, so that it holds for 4 views as
for 128). An edge-connected region of unobserved faces that borders the body is body: the visual hull closes the
cavities that no camera sees, such as the opening under a skirt between its hem and the legs, and no cloth spans
them. The other unobserved faces take the label of their neighbours (iterated over the face adjacency): a patch no
camera sees inside a garment stays garment. A final majority filter over edge-adjacent faces removes isolated
specks.
"""

from __future__ import annotations

import numpy as np

from pgc.geometry.raster import rasterize
from pgc.types import BACKGROUND_LABEL, BODY_LABEL, View


def face_adjacency(faces: np.ndarray) -> np.ndarray:
    """(P, 2) pairs of faces that share an edge (each pair once)."""
    f = np.asarray(faces, dtype=np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    fid = np.tile(np.arange(len(f)), 3)
    key = e[:, 0] * (int(e.max(initial=0)) + 1) + e[:, 1]
    order = np.argsort(key, kind="stable")
    key, fid = key[order], fid[order]
    same = key[1:] == key[:-1]
    return np.stack([fid[:-1][same], fid[1:][same]], axis=1)


def edge_components(selected: np.ndarray, adjacency: np.ndarray) -> np.ndarray:
    """(F,) id of the edge-connected component of every selected face (-1 for unselected faces)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    keep = selected[adjacency[:, 0]] & selected[adjacency[:, 1]]
    n = len(selected)
    g = coo_matrix((np.ones(int(keep.sum())), (adjacency[keep, 0], adjacency[keep, 1])), shape=(n, n))
    return np.where(selected, connected_components(g, directed=False)[1], -1)


def _boundary(seg: np.ndarray) -> np.ndarray:
    b = np.zeros(seg.shape, dtype=bool)
    b[:, 1:] |= seg[:, 1:] != seg[:, :-1]
    b[:, :-1] |= seg[:, 1:] != seg[:, :-1]
    b[1:] |= seg[1:] != seg[:-1]
    b[:-1] |= seg[1:] != seg[:-1]
    return b


def vote_face_labels(vertices: np.ndarray, faces: np.ndarray, views: list[View], num_labels: int,
                     depth_tolerance_px: float = 1.5, smooth_iterations: int = 2,
                     min_evidence: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Labels (F,) int32 and vote confidence (F,) in [0, 1] (winning share of the votes; 0 if unobserved).

    ``num_labels``: 1 + the largest segmentation id. ``depth_tolerance_px``: a face is visible when its
    centroid lies within this many pixel footprints of the z-buffer depth. ``min_evidence``: the share of the
    median face's evidence (the sum of the cosines of the views that see it on the person) a face needs to count
    as observed.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    tri = vertices[faces]
    centroid = tri.mean(1)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-30)
    votes = np.zeros((len(faces), num_labels))
    evidence = np.zeros(len(faces))
    for view in views:
        if view.segmentation is None:
            continue
        cam = view.camera
        depth = rasterize(cam, vertices, faces).depth
        uv, z = cam.project(centroid)
        ray = centroid - cam.center
        ray /= np.linalg.norm(ray, axis=1, keepdims=True)
        cos = -np.einsum("ij,ij->i", ray, normal)
        x, y = np.floor(uv[:, 0]), np.floor(uv[:, 1])
        ok = (cos > 0.05) & (z > 0) & (x >= 0) & (x < cam.width) & (y >= 0) & (y < cam.height)
        idx = np.nonzero(ok)[0]
        xi, yi = x[idx].astype(np.int64), y[idx].astype(np.int64)
        visible = z[idx] <= depth[yi, xi] + depth_tolerance_px * z[idx] / cam.fx
        idx, xi, yi = idx[visible], xi[visible], yi[visible]
        lab = view.segmentation[yi, xi].astype(np.int64)
        weight = cos[idx] * np.where(_boundary(view.segmentation)[yi, xi], 0.1, 1.0)
        keep = (lab != BACKGROUND_LABEL) & (lab < num_labels)
        np.add.at(votes, (idx[keep], lab[keep]), weight[keep])
        np.add.at(evidence, idx[keep], cos[idx[keep]])
    total = votes.sum(1)
    seen = evidence > 0  # some view saw the face on the person: it has votes
    observed = seen & (evidence >= min_evidence * np.median(evidence[seen])) if seen.any() else seen
    labels = votes.argmax(1)
    confidence = np.divide(votes.max(1), total, out=np.zeros_like(total), where=observed)
    adjacency = face_adjacency(faces)
    if BODY_LABEL < num_labels:
        body = _unobserved_beside(BODY_LABEL, labels, observed, adjacency)
        labels[body] = BODY_LABEL
        observed = observed | body
    labels = _fill_unseen(labels, observed, adjacency, num_labels)
    for _ in range(smooth_iterations):
        labels = _majority(labels, adjacency, num_labels)
    return labels.astype(np.int32), confidence


def _unobserved_beside(label: int, labels: np.ndarray, observed: np.ndarray, adjacency: np.ndarray) -> np.ndarray:
    """(F,) bool: the unobserved faces whose edge-connected unobserved region borders an observed ``label`` face."""
    region = edge_components(~observed, adjacency)
    borders = np.zeros(int(region.max(initial=-1)) + 1, bool)
    for a, b in ((0, 1), (1, 0)):
        src, dst = adjacency[:, a], adjacency[:, b]
        touch = observed[src] & (labels[src] == label) & (region[dst] >= 0)
        borders[region[dst[touch]]] = True
    return (region >= 0) & borders[np.maximum(region, 0)]


def _neighbour_counts(labels: np.ndarray, known: np.ndarray, adjacency: np.ndarray, num_labels: int) -> np.ndarray:
    counts = np.zeros((len(labels), num_labels))
    for a, b in ((0, 1), (1, 0)):
        src, dst = adjacency[:, a], adjacency[:, b]
        ok = known[src]
        np.add.at(counts, (dst[ok], labels[src[ok]]), 1.0)
    return counts


def _fill_unseen(labels: np.ndarray, seen: np.ndarray, adjacency: np.ndarray, num_labels: int) -> np.ndarray:
    labels, known = labels.copy(), seen.copy()
    while not known.all():
        counts = _neighbour_counts(labels, known, adjacency, num_labels)
        grow = ~known & (counts.sum(1) > 0)
        if not grow.any():  # components no view sees: the most common label overall
            labels[~known] = np.bincount(labels[known], minlength=num_labels).argmax() if known.any() else 0
            break
        labels[grow] = counts[grow].argmax(1)
        known |= grow
    return labels


def _majority(labels: np.ndarray, adjacency: np.ndarray, num_labels: int) -> np.ndarray:
    """Relabel faces whose edge neighbours (at least 2 of them) all agree on another label."""
    counts = _neighbour_counts(labels, np.ones(len(labels), bool), adjacency, num_labels)
    best = counts.argmax(1)
    flip = (best != labels) & (counts.max(1) >= 2) & (counts.max(1) == counts.sum(1))
    out = labels.copy()
    out[flip] = best[flip]
    return out
