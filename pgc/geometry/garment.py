"""The garment's faces on a labelled full-body mesh, with a clean boundary and one component.

Selecting faces (rather than rebuilding a mesh) keeps the face order of the full mesh, so anything bound to
its faces (Gaussians) carries over through ``Mesh.submesh``.
"""

from __future__ import annotations

import numpy as np

from pgc.errors import PGCDataError
from pgc.geometry.labels import edge_components, face_adjacency
from pgc.geometry.metrics import non_manifold_vertices
from pgc.types import Mesh


def largest_component(sel: np.ndarray, adj: np.ndarray) -> np.ndarray:
    if not sel.any():
        return sel
    comp = edge_components(sel, adj)
    return comp == np.bincount(comp[sel]).argmax()


def absorb_islands(sel: np.ndarray, adj: np.ndarray, min_faces: int) -> np.ndarray:
    """``sel`` plus the unselected edge-connected islands of fewer than ``min_faces`` faces."""
    comp = edge_components(~sel, adj)
    if not (comp >= 0).any():
        return sel
    sizes = np.bincount(comp[comp >= 0])
    return sel | ((comp >= 0) & (sizes[np.maximum(comp, 0)] < min_faces))


def garment_selection(mesh: Mesh, garment_ids: list[int], min_island_faces: int = 50,
                      max_rounds: int = 50) -> np.ndarray:
    """(F,) bool: the garment faces of ``mesh``.

    Label islands smaller than ``min_island_faces`` are absorbed (holes in the garment filled, specks
    outside dropped), then the largest edge-connected component is kept and, until nothing changes, 'ears'
    (faces with at most one selected edge neighbour) and faces at non-manifold (bow-tie) vertices are
    removed. The result is one edge-connected, edge- and vertex-manifold patch.
    """
    if mesh.face_labels is None:
        raise PGCDataError(f"mesh '{mesh.name}' has no face labels; run the label vote first")
    sel = np.isin(mesh.face_labels, garment_ids)
    if not sel.any():
        raise PGCDataError(f"no face of mesh '{mesh.name}' carries a garment label {list(garment_ids)}; "
                           "check the capture's segmentation and Capture.labels")
    adj = face_adjacency(mesh.faces)
    sel = absorb_islands(sel, adj, min_island_faces)
    sel = ~absorb_islands(~sel, adj, min_island_faces)
    sel = largest_component(sel, adj)
    for _ in range(max_rounds):
        inner = np.zeros(len(sel), np.int64)
        both = sel[adj[:, 0]] & sel[adj[:, 1]]
        np.add.at(inner, adj[both, 0], 1)
        np.add.at(inner, adj[both, 1], 1)
        drop = sel & (inner <= 1)
        bow = non_manifold_vertices(mesh.faces[sel], len(mesh.vertices))
        if len(bow):
            drop |= sel & np.isin(mesh.faces, bow).any(1)
        if not drop.any():
            break
        sel = largest_component(sel & ~drop, adj)
    if not sel.any():
        raise PGCDataError(f"mesh '{mesh.name}': the garment region vanished while cleaning its boundary "
                           "(it is only a few faces wide); check the segmentation")
    return sel
