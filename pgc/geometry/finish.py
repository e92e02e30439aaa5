"""Shared finishing steps of every reconstructor (pymeshlab + xatlas): clean, isotropic remesh to a target
vertex count, garment labels by multi-view voting, UV unwrap; and the garment sub-mesh.

All positions in world metres; faces counter-clockwise seen from outside. pymeshlab and xatlas (the extra
``pgc[meshlab]``) are imported when a step runs; a missing one raises :class:`pgc.errors.PGCPluginError`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from pgc.errors import PGCDataError, PGCPluginError
from pgc.events import Reporter
from pgc.geometry.options import FinishOptions
from pgc.geometry.labels import edge_components, face_adjacency, vote_face_labels
from pgc.geometry.metrics import topology_report
from pgc.types import Mesh, View


def _import(module: str) -> Any:
    """``module`` (pymeshlab or xatlas), or a :class:`PGCPluginError` naming the extra that installs it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise PGCPluginError(f"mesh finishing needs {module} ({exc}); install with: pip install 'pgc[meshlab]'") from exc


def _meshset(vertices: np.ndarray, faces: np.ndarray):
    pymeshlab = _import("pymeshlab")

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(vertices, np.float64),
                               face_matrix=np.asarray(faces, np.int32)))
    return ms


def _arrays(ms) -> tuple[np.ndarray, np.ndarray]:
    m = ms.current_mesh()
    return m.vertex_matrix().astype(np.float64), m.face_matrix().astype(np.int64)


def _repair(ms, min_component_fraction: float, max_hole_edges: int) -> None:
    ms.meshing_remove_duplicate_vertices()
    ms.meshing_remove_duplicate_faces()
    ms.meshing_remove_null_faces()
    ms.meshing_repair_non_manifold_edges(method="Remove Faces")
    ms.meshing_repair_non_manifold_vertices()
    ms.meshing_remove_unreferenced_vertices()
    largest = _largest_component_faces(ms)
    ms.meshing_remove_connected_component_by_face_number(
        mincomponentsize=max(int(min_component_fraction * largest), 1), removeunref=True)
    if max_hole_edges > 0:
        ms.meshing_close_holes(maxholesize=max_hole_edges, selfintersection=False)
        ms.meshing_repair_non_manifold_edges(method="Remove Faces")
        ms.meshing_repair_non_manifold_vertices()


def _drop_non_manifold_edges(faces: np.ndarray) -> np.ndarray:
    """Remove every face touching a vertex of an edge shared by more than two faces. Removing only some of
    the faces at such an edge can join two sheets with opposite orientation; a clean ring-shaped hole that
    hole filling closes is safer."""
    f = np.asarray(faces, dtype=np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    bad = np.unique(uniq[counts > 2])
    return f[~np.isin(f, bad).any(1)] if len(bad) else f


def _largest_component_faces(ms) -> int:
    _, f = _arrays(ms)
    return int(np.bincount(edge_components(np.ones(len(f), bool), face_adjacency(f))).max())


def clean(vertices: np.ndarray, faces: np.ndarray, min_component_fraction: float = 0.02,
          max_hole_edges: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Remove duplicates, null faces, non-manifold edges/vertices and small components; close small holes;
    orient faces coherently, outward (positive signed volume for closed meshes)."""
    if len(faces) == 0:
        raise PGCDataError("cannot clean an empty mesh (no faces)")
    ms = _meshset(vertices, _drop_non_manifold_edges(faces))
    _repair(ms, min_component_fraction, max_hole_edges)
    v, f = _arrays(ms)
    if len(f) == 0:
        raise PGCDataError("cleaning removed every face: the surface is degenerate")
    return v, orient(v, f)


def orient(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Faces oriented coherently within each edge-connected component (breadth-first over a spanning tree)
    and outward: a component with negative signed volume is flipped as a whole."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    f = np.asarray(f, dtype=np.int64).copy()
    n = len(f)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    fid = np.tile(np.arange(n), 3)
    key = np.minimum(e[:, 0], e[:, 1]) * len(v) + np.maximum(e[:, 0], e[:, 1])
    forward = e[:, 0] < e[:, 1]
    order = np.argsort(key, kind="stable")
    key, fid, forward = key[order], fid[order], forward[order]
    pair = key[1:] == key[:-1]
    a, b = fid[:-1][pair], fid[1:][pair]
    # Two faces sharing an edge agree when they traverse it in opposite directions.
    disagree = forward[:-1][pair] == forward[1:][pair]
    g = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)).tocsr()
    pair_key = np.concatenate([a * n + b, b * n + a])
    pair_dis = np.concatenate([disagree, disagree])
    srt = np.argsort(pair_key)
    pair_key, pair_dis = pair_key[srt], pair_dis[srt]
    flip = np.zeros(n, dtype=bool)
    ncomp, comp = connected_components(g, directed=False)
    roots = np.unique(comp, return_index=True)[1]
    for root in roots:
        nodes, pred = breadth_first_order(g, int(root), directed=False)
        child = nodes[1:]
        parent = pred[child]
        dis = pair_dis[np.searchsorted(pair_key, parent * n + child)].tolist()
        fl = flip.tolist()
        for node, par, d in zip(child.tolist(), parent.tolist(), dis):
            fl[node] = fl[par] ^ d
        flip = np.asarray(fl)
    f[flip] = f[flip][:, ::-1]
    t = v[f]
    vol = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])) / 6.0
    inward = np.bincount(comp, weights=vol, minlength=ncomp)[comp] < 0
    f[inward] = f[inward][:, ::-1]
    return f


PREDECIMATE_ABOVE = 16
"""Remeshing input finer than this many times the target vertex count is first decimated to
:data:`PREDECIMATE_TO` times it: each remeshing pass costs time in proportion to its input, and a surface
this much finer than the output holds no shape the output's edges could follow."""
PREDECIMATE_TO = 8


def decimate(vertices: np.ndarray, faces: np.ndarray, target_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadric edge-collapse decimation (pymeshlab; boundaries and normals preserved, vertices placed at the
    quadric optimum) to about ``target_vertices``."""
    _import("pymeshlab")
    ms = _meshset(vertices, faces)
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(2 * target_vertices), preserveboundary=True,
                                                boundaryweight=1.0, preservenormal=True, optimalplacement=True,
                                                planarquadric=True, autoclean=True)
    return _arrays(ms)


def remesh(vertices: np.ndarray, faces: np.ndarray, target_vertices: int, iterations: int = 6,
           passes: int = 3, tolerance: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Isotropic explicit remeshing to about ``target_vertices`` (within ``tolerance``, up to ``passes``
    passes that rescale the edge length by sqrt(V / target)), then sliver removal and repair. Input more
    than :data:`PREDECIMATE_ABOVE` times finer than the target is decimated first (:func:`decimate`)."""
    pymeshlab = _import("pymeshlab")

    if len(vertices) > PREDECIMATE_ABOVE * target_vertices:
        vertices, faces = decimate(vertices, faces, PREDECIMATE_TO * target_vertices)
    area = Mesh(vertices, faces).face_areas().sum()
    # An equilateral mesh with V vertices has about 2V faces of area sqrt(3)/4 L^2.
    length = float(np.sqrt(2.0 * area / (np.sqrt(3.0) * target_vertices)))
    for _ in range(passes):
        ms = _meshset(vertices, faces)
        ms.meshing_isotropic_explicit_remeshing(iterations=iterations, targetlen=pymeshlab.PureValue(length),
                                                featuredeg=180.0, checksurfdist=True,
                                                maxsurfdist=pymeshlab.PureValue(0.5 * length))
        v, f = _arrays(ms)
        ratio = len(v) / target_vertices
        if abs(ratio - 1.0) <= tolerance:
            break
        length *= float(np.sqrt(ratio))
    return remove_slivers(v, f)


def remove_slivers(vertices: np.ndarray, faces: np.ndarray, min_angle_deg: float = 10.0,
                   rounds: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Collapse the shortest edge of every triangle with an angle under ``min_angle_deg`` (its two vertices
    meet at the edge midpoint), a vertex-disjoint set of edges per round; faces that become degenerate are
    dropped and the mesh is repaired (non-manifold pieces removed, holes closed, re-oriented)."""
    from pgc.geometry.metrics import triangle_angles_deg

    v, f = np.asarray(vertices, np.float64).copy(), np.asarray(faces, np.int64)
    for _ in range(rounds):
        bad = np.nonzero(triangle_angles_deg(Mesh(v, f)).min(1) < min_angle_deg)[0]
        if len(bad) == 0:
            break
        t = v[f[bad]]
        lengths = np.stack([np.linalg.norm(t[:, (k + 1) % 3] - t[:, k], axis=1) for k in range(3)], 1)
        k = lengths.argmin(1)
        a, b = f[bad, k], f[bad, (k + 1) % 3]
        used = np.zeros(len(v), bool)
        remap = np.arange(len(v))
        for i, j in zip(a.tolist(), b.tolist()):  # a vertex-disjoint set of collapses
            if used[i] or used[j]:
                continue
            used[i] = used[j] = True
            v[i] = 0.5 * (v[i] + v[j])
            remap[j] = i
        f = remap[f]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    ms = _meshset(v, _drop_non_manifold_edges(f))
    _repair(ms, 0.0, 16)
    v, f = _arrays(ms)
    return v, orient(v, f)


def unwrap(vertices: np.ndarray, faces: np.ndarray, resolution: int = 1024, padding: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """xatlas UV atlas: ``uv`` (T, 2) float32 in [0, 1] (v up) and ``face_uv`` (F, 3) int64, face order kept."""
    xatlas = _import("xatlas")
    atlas = xatlas.Atlas()
    atlas.add_mesh(np.asarray(vertices, np.float32), np.asarray(faces, np.uint32))
    pack = xatlas.PackOptions()
    pack.resolution = int(resolution)
    pack.padding = int(padding)
    pack.bilinear = True
    atlas.generate(xatlas.ChartOptions(), pack)
    vmapping, indices, uvs = atlas[0]
    if not np.array_equal(np.asarray(vmapping)[indices], faces):
        raise RuntimeError("xatlas changed the face order or topology; cannot map UVs back")
    return uvs.astype(np.float32), indices.astype(np.int64)


def finish(vertices: np.ndarray, faces: np.ndarray, views: list[View], labels: dict[int, str],
           options: FinishOptions, reporter: Reporter | None = None, name: str = "reconstruction",
           keep_topology: bool = False) -> tuple[Mesh, dict[str, Any]]:
    """Raw surface -> cleaned, remeshed, labelled, UV-mapped mesh, and figures (seconds per step,
    topology report, label vote confidence). ``keep_topology`` skips hole filling and remeshing (a user's
    simulation-ready mesh: only repairs of broken pieces change it)."""
    reporter = reporter or Reporter.silent()
    figures: dict[str, Any] = {"raw_vertices": int(len(vertices)), "raw_faces": int(len(faces))}
    t0 = time.perf_counter()
    with reporter.stage("mesh.clean"):
        v, f = clean(vertices, faces, options.min_component_fraction, 0 if keep_topology else options.max_hole_edges)
    t1 = time.perf_counter()
    if not keep_topology:
        with reporter.stage("mesh.remesh", target_vertices=options.target_vertices):
            v, f = remesh(v, f, options.target_vertices, options.remesh_iterations)
    t2 = time.perf_counter()
    with reporter.stage("mesh.labels"):
        face_labels, confidence = vote_face_labels(v, f, views, max(labels) + 1, options.label_depth_tolerance_px,
                                                   options.label_smooth_iterations, options.label_min_evidence)
    t3 = time.perf_counter()
    with reporter.stage("mesh.uv"):
        uv, face_uv = unwrap(v, f, options.uv_resolution, options.uv_padding)
    t4 = time.perf_counter()
    mesh = Mesh(v, f, uv, face_uv, face_labels, name=name)
    figures.update(seconds_clean=t1 - t0, seconds_remesh=t2 - t1, seconds_labels=t3 - t2, seconds_uv=t4 - t3,
                   label_confidence_mean=float(confidence[confidence > 0].mean()) if (confidence > 0).any() else 0.0,
                   label_unseen_fraction=float(np.mean(confidence == 0)), **topology_report(mesh))
    return mesh, figures


def extract_garment(mesh: Mesh, garment_ids: list[int], min_island_faces: int = 50, resolution: int = 1024,
                    padding: int = 2) -> tuple[Mesh, np.ndarray]:
    """The garment sub-mesh (:func:`pgc.geometry.garment.garment_selection`: one component, clean manifold
    boundary) with its own xatlas UV atlas, and the (F,) bool face selection on ``mesh``. The sub-mesh keeps
    the order of the selected faces, so face-bound data (Gaussians) carries over."""
    from pgc.geometry.garment import garment_selection

    sel = garment_selection(mesh, garment_ids, min_island_faces)
    sub, _ = mesh.submesh(sel, name=f"{mesh.name}-garment" if mesh.name else "garment")
    uv, face_uv = unwrap(sub.vertices, sub.faces, resolution, padding)
    return Mesh(sub.vertices, sub.faces, uv, face_uv, sub.face_labels, name=sub.name), sel
