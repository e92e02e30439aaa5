"""The body fit: a body model's shape, joint rotations and translation fitted to a capture's silhouettes,
segmentation labels and optional 2D keypoints (torch, through the role's differentiable ``forward_torch``).

Per view (every length in pixels of that view):
- the body's silhouette near its edge is ``s = sigmoid(d / sigma)``, ``d`` the signed distance of a pixel
  centre to the nearest projected contour edge (edges between a front- and a back-facing face; + inside the
  rasterised body); at ``sigma`` about 1/4 px it matches a box-filtered edge, the capture mask's coverage;
- pixels labelled body must be covered as much as the mask says: ``(s - mask)^2``; every other pixel may be
  covered at most that much: ``relu(s - mask)^2`` (a garment may hide body, never the background);
- every vertex projects inside the person's mask: the squared distance, beyond a pixel, to the mask;
- reach: every body-labelled pixel the body does not cover pulls the body's silhouette to it (its squared distance,
  beyond a pixel, to the nearest contour edge), long-range where the silhouette term saturates;
- keypoints (:mod:`pgc.io.keypoints`): the squared pixel distance of the projected joints, by confidence;
- a prior on the squared joint angles keeps what no view constrains at rest.
Three phases narrow ``sigma`` (:data:`PHASES`; the silhouette term is scaled by ``sigma`` so its gradient keeps its
size) and the band of pixels around the edge; the first two run on images downsampled to about :data:`COARSE_PX`
pixels. The start shape's height comes from a search over the height parameter (:func:`_start_search`), its gender
from a choice among a few as tall (:func:`_alternative_start`); the start translation brings the body's visible
silhouette onto the masks (:func:`_placed_translation`); the views used are chosen far apart (:func:`spread_views`);
every joint that moves enough skin is posed (those that with their descendants skin less than
:data:`MIN_SUBTREE_SKIN` of the vertices, hands' fingers and feet, stay at rest); a phase stops once its loss stalls
(:data:`STALL_SHARE`), the last also when it no longer falls (``tolerance``). Docs: docs/body.md, "Body fit".
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.roles.body_model import BodyModel
from pgc.types import BODY_LABEL, Capture, Mesh

if TYPE_CHECKING:
    import torch

    from pgc.stages.body_fit import BodyFitSettings

PHASES = ((0.25, 1.5, True), (0.4, 0.6, True), (0.35, 0.3, False))
"""(share of the iterations, silhouette edge width sigma in pixels of the phase's images, whether the phase runs on
the coarse images) of the coarse-to-fine phases."""
COARSE_PX = 96
"""Coarse phases run on the images downsampled by the integer factor that brings their larger side nearest this
many pixels (none for images this small)."""
STALL_SHARE = 0.5
"""A phase stops once its loss has not reached a new low for this share of the phase's steps."""
START_PARAMETER = "height"
"""The shape parameter searched for the start (:func:`_start_search`), when the body model has it."""
START_VALUES = 5
"""Values of :data:`START_PARAMETER` the start search evaluates, evenly over its range (ends excluded)."""
START_ALTERNATIVES = ("gender", (0.1, 0.5, 0.9))
"""A shape parameter and its start values, when the body model has it (:func:`_alternative_start`): the searched
start at each value, as tall, placed alike; the value whose body lies best inside the masks starts the fit, with the
height searched again at it. Anny's gender: the descent barely moves it from its start."""
BAND_SIGMAS = 6.0
"""Pixels within this many sigmas (at least BAND_MIN_PX) of the body's edge carry the silhouette loss."""
BAND_MIN_PX = 2.0
INSIDE_WEIGHT = 0.05
"""Weight of the vertices-inside-the-mask term (px^2 per vertex) against the silhouette term."""
INSIDE_TOLERANCE_PX = 1.0
"""The vertices-inside term counts a vertex's distance beyond this many pixels outside the person's mask."""
REACH_WEIGHT = 0.05
"""Weight of the reach term (px^2 per body-labelled pixel) against the silhouette term."""
REACH_TOLERANCE_PX = 1.0
"""The reach term counts a body-labelled pixel's distance beyond this many pixels from the body's silhouette."""
KEYPOINT_WEIGHT = 0.01
"""Weight of the keypoint term (px^2 per joint)."""
MIN_SUBTREE_SKIN = 0.08
"""Joints that, with their descendants, skin less than this fraction of the vertices (Anny's fingers, thumbs, feet
and toes) are not posed: at a few pixels across, their silhouette does not fix their rotation."""
PLACEMENT_ROUNDS = 10
"""Most rounds of the start translation's centroid matching (:func:`_placed_translation`)."""
TRANSLATION_SCALE = 0.1
"""Metres per unit of the optimised translation (so one learning rate suits angles, shape and position)."""


@dataclass(frozen=True)
class Keypoints:
    """2D keypoints of one view: joint names, pixel positions (N, 2) (centres at integer + 0.5), confidence (N,)."""

    names: tuple[str, ...]
    xy: np.ndarray
    confidence: np.ndarray


@dataclass(frozen=True)
class BodyFit:
    """A fitted body: which model, its shape, pose and mesh, and the fit's figures."""

    model: str
    """The body_model implementation's name (``anny``, ``smplx``)."""
    options: dict[str, Any]
    """Its options (Anny's topology, the SMPL file), needed to rebuild the body."""
    shape: dict[str, float]
    joint_names: tuple[str, ...]
    rotations: np.ndarray
    """(J, 3, 3) local joint rotations (the role's convention)."""
    translation: np.ndarray
    """(3,) metres."""
    mesh: Mesh
    """The posed body (label body on every face)."""
    figures: dict[str, Any]


@dataclass
class _ViewData:
    """What a view contributes, precomputed once (numpy, then torch where the loss reads it)."""

    name: str
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int
    mask: np.ndarray
    """(H, W) person coverage in [0, 1]."""
    body: np.ndarray
    """(H, W) bool: pixels labelled body."""
    outside: "torch.Tensor"
    """(H + 2, W + 2) distance (px) to the mask, 0 inside and on the one-pixel frame outside the image."""
    keypoints: Keypoints | None
    scale: int = 1
    """Full-resolution pixels per pixel of these images (the coarse phases' downsampling factor)."""


def check_capture_layers(capture: Capture, where: str) -> None:
    """Refuse a capture the fit cannot use: every view needs segmentation labels (0 background, 1 body,
    garments above); masks are optional (the labels' foreground stands in)."""
    from pgc.io.capture_checks import require_segmentation

    require_segmentation(capture, where, "the body fit")
    if not any((v.segmentation == BODY_LABEL).any() for v in capture.views):
        raise PGCDataError(f"{where}: no pixel of any view is labelled body ({BODY_LABEL}) in the segmentation; the "
                           "fit needs the visible skin labelled (0 background, 1 body, 2 garment)")


def _outside(person: np.ndarray) -> "torch.Tensor":
    """(H + 2, W + 2) distance (px), beyond :data:`INSIDE_TOLERANCE_PX`, of each pixel to the ``person`` (H, W) bool
    pixels, on a one-pixel frame of zeros (nothing is known beyond the image)."""
    import torch
    from scipy.ndimage import distance_transform_edt

    outside = np.maximum(distance_transform_edt(~person) - INSIDE_TOLERANCE_PX, 0.0)
    return torch.as_tensor(np.pad(outside, 1), dtype=torch.float32)


def _view_data(view, keypoints: Keypoints | None) -> _ViewData:
    seg = view.segmentation
    mask = view.mask if view.mask is not None else (seg != 0).astype(np.float32)
    person = (mask >= 0.5) | (seg != 0)
    cam = view.camera
    return _ViewData(cam.name, cam.K, cam.R, cam.t, cam.width, cam.height, np.clip(mask, 0.0, 1.0),
                     seg == BODY_LABEL, _outside(person), keypoints)


def coarse_factor(width: int, height: int) -> int:
    """The integer downsampling factor of the coarse phases: the larger image side over :data:`COARSE_PX`, rounded
    (at least 1)."""
    return max(1, int(round(max(width, height) / COARSE_PX)))


def _downsampled(v: _ViewData, f: int) -> _ViewData:
    """``v`` at 1/``f`` of its resolution (the trailing rows and columns that fill no whole block dropped): the
    mask's block means; body where the block's body pixels are at least its other person pixels; the person, for
    the vertices-inside term, where any pixel of the block is; the camera's intrinsics scaled alike."""
    if f == 1:
        return v
    h, w = v.height // f, v.width // f

    def blocks(a: np.ndarray) -> np.ndarray:
        return a[:h * f, :w * f].reshape(h, f, w, f).astype(np.float64).mean(axis=(1, 3))

    person_fine = (v.mask >= 0.5) | v.body
    body = blocks(v.body)
    person = blocks(person_fine)
    K = np.diag([1.0 / f, 1.0 / f, 1.0]) @ v.K
    return _ViewData(v.name, K, v.R, v.t, w, h, blocks(v.mask), (body > 0) & (2 * body >= person),
                     _outside(person > 0), v.keypoints, f)


def spread_views(cameras: list, count: int) -> list[int]:
    """Indices of ``count`` of ``cameras`` chosen far apart: from the first, each next the camera whose optical
    axis makes the largest smallest angle with those chosen (all of them when there are fewer)."""
    if count >= len(cameras):
        return list(range(len(cameras)))
    axes = np.array([np.asarray(c.R)[2] for c in cameras], np.float64)
    chosen = [0]
    nearest = axes @ axes[0]  # cosine to the nearest chosen axis
    for _ in range(count - 1):
        nearest[chosen] = np.inf
        nxt = int(np.argmin(nearest))
        chosen.append(nxt)
        nearest = np.maximum(nearest, axes @ axes[nxt])
    return sorted(chosen)


def _rodrigues(w: "torch.Tensor") -> "torch.Tensor":
    """Rotation matrices (..., 3, 3) of axis-angle vectors (..., 3) (smooth at zero)."""
    import torch

    theta2 = (w * w).sum(-1, keepdim=True)[..., None]
    theta = torch.sqrt(theta2 + 1e-12)
    x, y, z = w.unbind(-1)
    zero = torch.zeros_like(x)
    k = torch.stack([zero, -z, y, z, zero, -x, -y, x, zero], -1).reshape(*w.shape[:-1], 3, 3)
    a = torch.sin(theta) / theta
    b = (1.0 - torch.cos(theta)) / (theta2 + 1e-12)
    b = torch.where(theta2 < 1e-8, 0.5 - theta2 / 24.0, b)
    return torch.eye(3, dtype=w.dtype) + a * k + b * (k @ k)


def _edge_faces(faces: np.ndarray) -> np.ndarray:
    """(E, 4): vertex a, vertex b, and the two faces of each edge of a closed mesh (edges with one face
    repeat it)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    f = np.tile(np.arange(len(faces)), 3)
    key = np.sort(e, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, f = key[order], f[order]
    first = np.r_[True, np.any(key[1:] != key[:-1], axis=1)]
    start = np.nonzero(first)[0]
    count = np.diff(np.r_[start, len(key)])
    other = np.where(count > 1, start + 1, start)
    return np.column_stack([key[start], f[start], f[other]])


def posed_joints(body: BodyModel) -> np.ndarray:
    """(J,) bool: the joints the fit poses (:data:`MIN_SUBTREE_SKIN`)."""
    subtree = np.asarray(body.weights).sum(axis=0) / len(body.weights)
    parents = np.asarray(body.parents)
    for j in range(len(parents) - 1, -1, -1):  # parents come before their children
        if parents[j] >= 0:
            subtree[parents[j]] += subtree[j]
    return subtree >= MIN_SUBTREE_SKIN


def _centroid_point(views: list[_ViewData], centroids: list[np.ndarray | None]) -> np.ndarray:
    """The point nearest the rays through the views' pixel ``centroids`` (least squares; None: the view has none),
    metres."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for v, c in zip(views, centroids):
        if c is None:
            continue
        d = v.R.T @ np.linalg.solve(v.K, np.array([c[0], c[1], 1.0]))
        d /= np.linalg.norm(d)
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ (-v.R.T @ v.t)
    if np.linalg.matrix_rank(A) < 3:
        raise PGCDataError("body fit: the masks' centroids do not locate the person in 3D (one view, or parallel "
                           "rays); use views from several directions")
    return np.linalg.solve(A, b)


def _pixel_centroid(covered: np.ndarray) -> np.ndarray | None:
    """(x, y) pixel-centre centroid of a boolean image, None when it is empty."""
    ys, xs = np.nonzero(covered)
    return np.array([xs.mean() + 0.5, ys.mean() + 0.5]) if len(xs) else None


def _translation_init(views: list[_ViewData]) -> np.ndarray:
    """The point nearest the rays through the centroids of the views' masks (least squares), metres."""
    return _centroid_point(views, [_pixel_centroid(v.mask >= 0.5) for v in views])


def _facing(tri: np.ndarray) -> np.ndarray:
    """(F,) bool: the projected triangles ``tri`` (F, 3, 2) px turned to the camera (positive signed area)."""
    return (tri[:, 1, 0] - tri[:, 0, 0]) * (tri[:, 2, 1] - tri[:, 0, 1]) \
        - (tri[:, 2, 0] - tri[:, 0, 0]) * (tri[:, 1, 1] - tri[:, 0, 1]) > 0


def _coverage(uv: np.ndarray, depth: np.ndarray, faces: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W) bool: the pixel centres a mesh covers, projected to ``uv`` (V, 2) px with camera depths (V,) (faces
    with a vertex behind the camera are left out; of a closed mesh, the faces turned to the camera cover the same).
    Scanline rasterisation: each triangle's span of pixel centres on each row it crosses, summed as +1 / -1 marks
    along the row."""
    tri = uv[faces[np.all(depth[faces] > 1e-3, axis=1)]]
    ty = tri[..., 1]
    y0 = np.clip(np.ceil(np.minimum(np.minimum(ty[:, 0], ty[:, 1]), ty[:, 2]) - 0.5), 0, height).astype(np.int64)
    y1 = np.clip(np.floor(np.maximum(np.maximum(ty[:, 0], ty[:, 1]), ty[:, 2]) - 0.5), -1, height - 1).astype(np.int64)
    rows = np.maximum(y1 - y0 + 1, 0)
    owner = np.repeat(np.arange(len(tri)), rows)
    y = y0[owner] + np.arange(len(owner)) - np.repeat(np.cumsum(rows) - rows, rows)
    a = tri[owner]
    b = a[:, [1, 2, 0]]  # the triangle's edges a -> b
    yc = (y + 0.5)[:, None]
    ay, by = a[..., 1], b[..., 1]
    lo, hi = np.minimum(ay, by), np.maximum(ay, by)
    crosses = (yc >= lo) & (yc <= hi) & (hi > lo)
    x = a[..., 0] + (yc - ay) * (b[..., 0] - a[..., 0]) / np.where(hi > lo, by - ay, 1.0)
    left, right = np.where(crosses, x, np.inf), np.where(crosses, x, -np.inf)
    x0 = np.clip(np.ceil(np.minimum(np.minimum(left[:, 0], left[:, 1]), left[:, 2]) - 0.5), 0, width)
    x1 = np.clip(np.floor(np.maximum(np.maximum(right[:, 0], right[:, 1]), right[:, 2]) - 0.5), -1, width - 1)
    span = x1 >= x0
    y, x0, x1 = y[span], x0[span].astype(np.int64), x1[span].astype(np.int64)
    n = height * (width + 1)
    marks = np.bincount(y * (width + 1) + x0, minlength=n) - np.bincount(y * (width + 1) + x1 + 1, minlength=n)
    return np.cumsum(marks.reshape(height, width + 1), axis=1)[:, :width] > 0


def _dilated(a: np.ndarray, radius: float) -> np.ndarray:
    """(H, W) bool: the pixels whose centre lies within ``radius`` px of the centre of a True pixel of ``a`` (H, W)
    bool (nothing beyond its border): per row offset ``dy``, the rows dilated by the widest ``dx`` with
    ``dx^2 + dy^2 <= radius^2``, moved by ``dy``."""
    from scipy.ndimage import maximum_filter1d

    out = np.zeros_like(a)
    H = a.shape[0]
    r = min(int(np.floor(radius)), H - 1)
    rows: dict[int, np.ndarray] = {}
    for dy in range(-r, r + 1):
        w = int(np.floor(np.sqrt(radius * radius - dy * dy)))
        if w not in rows:
            rows[w] = maximum_filter1d(a.view(np.uint8), 2 * w + 1, axis=1, mode="constant").view(bool)
        if dy >= 0:
            out[dy:] |= rows[w][:H - dy]
        else:
            out[:H + dy] |= rows[w][-dy:]
    return out


def _edge_band(covered: np.ndarray, width_px: float) -> np.ndarray:
    """(H, W) bool: the pixels whose centre lies within ``width_px`` of a pixel centre on the other side of the
    ``covered`` (H, W) bool region's edge (:func:`_dilated`, on the region's box widened by more than ``width_px``,
    where every such pixel lies); none when nothing is covered."""
    band = np.zeros_like(covered)
    rows, cols = np.nonzero(covered.any(axis=1))[0], np.nonzero(covered.any(axis=0))[0]
    if len(rows) == 0:
        return band
    m = int(np.floor(width_px)) + 1
    box = np.s_[max(rows[0] - m, 0):rows[-1] + m + 1, max(cols[0] - m, 0):cols[-1] + m + 1]
    c = covered[box]
    band[box] = np.where(c, _dilated(~c, width_px), _dilated(c, width_px))
    return band


def _placed_translation(views: list[_ViewData], vertices: np.ndarray, silhouette: "_Silhouette") -> np.ndarray:
    """The translation (metres) that puts a body's ``vertices`` where the masks are: its visible silhouette's
    centroids brought onto the masks' centroids (both cut by the image borders alike, so a framing that shows part
    of the body places it right), by :data:`PLACEMENT_ROUNDS` fixed-point rounds from its box centre."""
    target = _translation_init(views)
    shift = target - 0.5 * (vertices.min(0) + vertices.max(0))
    for _ in range(PLACEMENT_ROUNDS):
        centroids = []
        for v in views:
            pc = (vertices + shift) @ v.R.T + v.t
            uv = (pc @ v.K.T)[:, :2] / np.maximum(pc[:, 2:3], 1e-3)
            facing = _facing(uv[silhouette.faces])
            centroids.append(_pixel_centroid(silhouette.covered(uv, pc[:, 2], facing, v.width, v.height)))
        if any(c is None for c in centroids):
            break
        step = target - _centroid_point(views, centroids)
        shift = shift + step
        if np.linalg.norm(step) < 1e-3:
            break
    return shift


@dataclass(frozen=True)
class _EdgePixels:
    """The pixels of a view that the silhouette and reach terms read at one step (numpy): those in the band around
    the body's edge and the body-labelled ones it does not cover."""

    edge: np.ndarray
    """(M, 2) the two vertices of each pixel's nearest contour edge."""
    centre: np.ndarray
    """(M, 2) the pixel centres, px."""
    covered: np.ndarray
    """(M,) bool: the body covers the pixel centre."""
    mask: np.ndarray
    """(M,) the mask's coverage."""
    body: np.ndarray
    """(M,) bool: labelled body."""
    in_band: np.ndarray
    """(M,) bool: in the band (the others are only unreached)."""
    unreached: np.ndarray
    """(M,) bool: labelled body, in the mask and not covered."""
    body_pixels: int
    """The view's body-labelled mask pixels (the reach term's denominator), at least 1."""
    iou: float
    """The hard silhouette's IoU with the mask."""


def _edge_terms(uv: "torch.Tensor", parts: list[_EdgePixels], sigma: float
                ) -> list[tuple["torch.Tensor", "torch.Tensor"]]:
    """Per view of ``parts`` (its vertices the rows of ``uv`` (views x V, 2) px, view after view): the silhouette
    term (the mean over the band of ``(s - mask)^2`` on body pixels, ``relu(s - mask)^2`` on the others, ``s`` the
    soft coverage at edge width ``sigma`` px; 0 without a band) and the reach term (the squared distance, beyond
    :data:`REACH_TOLERANCE_PX`, of each unreached pixel to its nearest contour edge, summed, per body pixel). One
    set of operations for all views; the sigmoid and the sums apart per view, so each view's figures are those of
    its pixels alone, to the bit."""
    import torch

    vertices = len(uv) // len(parts)

    def cat(name: str) -> "torch.Tensor":
        return torch.as_tensor(np.concatenate([getattr(x, name) for x in parts]))

    edge = np.concatenate([x.edge + k * vertices for k, x in enumerate(parts)])
    sizes = [len(x.centre) for x in parts]
    ea, eb = uv[torch.as_tensor(edge[:, 0])], uv[torch.as_tensor(edge[:, 1])]
    q = cat("centre").to(uv.dtype)
    ab = eb - ea
    s = ((q - ea) * ab).sum(-1) / (ab * ab).sum(-1).clamp_min(1e-9)
    closest = ea + s.clamp(0.0, 1.0)[:, None] * ab
    dist = torch.sqrt(((q - closest) ** 2).sum(-1) + 1e-9)
    signed = torch.where(cat("covered"), dist, -dist)
    soft = torch.cat([torch.sigmoid(x) for x in (signed / sigma).split(sizes)])
    diff = soft - cat("mask").to(uv.dtype)
    per_pixel = torch.where(cat("body"), diff * diff, torch.relu(diff) ** 2)
    in_band = cat("in_band")
    silhouette = per_pixel[in_band].split([int(x.in_band.sum()) for x in parts])
    far = torch.relu(dist - REACH_TOLERANCE_PX) ** 2
    reach = torch.where(cat("unreached"), far, 0.0).split(sizes)
    zero = uv.sum() * 0.0
    return [(sil.mean() if len(sil) else zero, r.sum() / x.body_pixels)
            for sil, r, x in zip(silhouette, reach, parts)]


class _Silhouette:
    """Per view and step: the body's soft silhouette near its edge and the losses on it."""

    def __init__(self, faces: np.ndarray) -> None:
        self.faces = faces
        self.edges = _edge_faces(faces)
        # every edge has two faces: the faces turned to the camera cover what the mesh covers
        self.closed = bool(np.all(self.edges[:, 2] != self.edges[:, 3]))

    def covered(self, p: np.ndarray, depth: np.ndarray, facing: np.ndarray, width: int, height: int) -> np.ndarray:
        """(H, W) bool: the pixel centres the mesh covers, its vertices projected to ``p`` (V, 2) px at camera depths
        (V,), ``facing`` (F,) its faces turned to the camera (:func:`_coverage` of those alone when it is closed)."""
        return _coverage(p, depth, self.faces[facing] if self.closed else self.faces, width, height)

    def pixels(self, v: _ViewData, p: np.ndarray, depth: np.ndarray, sigma: float) -> _EdgePixels:
        """The pixels the silhouette and reach terms read of view ``v`` with the body's vertices projected to ``p``
        (V, 2) px at camera depths (V,): the band within :data:`BAND_SIGMAS` ``sigma`` (at least
        :data:`BAND_MIN_PX`) of the body's edge, and the body-labelled mask pixels it does not cover; each with its
        nearest contour edge (through points sampled every half pixel along the projected edges)."""
        from scipy.spatial import cKDTree

        facing = _facing(p[self.faces])
        covered = self.covered(p, depth, facing, v.width, v.height)
        target = v.mask >= 0.5
        union = (covered | target).sum()
        iou = float((covered & target).sum() / union) if union else 1.0
        # contour edges: one adjacent face turned to the camera, the other away
        contour = self.edges[facing[self.edges[:, 2]] != facing[self.edges[:, 3]]][:, :2]
        band = _edge_band(covered, max(BAND_MIN_PX, BAND_SIGMAS * sigma) + 0.5)
        unreached = v.body & target & ~covered
        ys, xs = np.nonzero(band | unreached)
        if len(contour) == 0:
            ys = xs = np.zeros(0, np.int64)
        centres = np.column_stack([xs + 0.5, ys + 0.5])
        nearest = np.zeros(0, np.int64)
        if len(xs):
            a, b = p[contour[:, 0]], p[contour[:, 1]]
            steps = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) * 2).astype(int), 1) + 1
            edge_of = np.repeat(np.arange(len(contour)), steps)
            first = np.repeat(np.cumsum(steps) - steps, steps)
            frac = (np.arange(len(edge_of)) - first) / np.repeat(steps - 1, steps)
            nearest = edge_of[cKDTree(a[edge_of] + frac[:, None] * (b - a)[edge_of]).query(centres)[1]]
        return _EdgePixels(contour[nearest], centres, covered[ys, xs], v.mask[ys, xs], v.body[ys, xs], band[ys, xs],
                           unreached[ys, xs], max(int((v.body & target).sum()), 1), iou)

    def loss(self, v: _ViewData, uv: "torch.Tensor", depth: "torch.Tensor", sigma: float
             ) -> tuple["torch.Tensor", "torch.Tensor", float]:
        """The silhouette loss of one view (mean over the band's pixels), the reach loss (px^2 per body-labelled
        pixel) and the IoU of the hard silhouette with the mask, of the body projected to ``uv`` (V, 2) px at camera
        depths (V,)."""
        px = self.pixels(v, uv.detach().double().numpy(), depth.detach().double().numpy(), sigma)
        return (*_edge_terms(uv, [px], sigma)[0], px.iou)


def _sample_outside(outside: "torch.Tensor", uv: "torch.Tensor") -> "torch.Tensor":
    """Bilinear samples (px) of padded distance images (views, H, W) (or one, (H, W)) at pixel positions ``uv``
    (views x N, 2) (N per image, image after image); 0 beyond the frame."""
    import torch

    H, W = outside.shape[-2:]
    x = (uv[:, 0] - 0.5 + 1.0).clamp(0.0, W - 1.001)
    y = (uv[:, 1] - 0.5 + 1.0).clamp(0.0, H - 1.001)
    x0, y0 = x.floor().long(), y.floor().long()
    fx, fy = x - x0, y - y0
    g = outside.to(uv.dtype).reshape(-1)
    images = len(g) // (H * W)
    first = torch.arange(images).repeat_interleave(len(uv) // images) * (H * W) + y0 * W + x0
    return ((1 - fx) * (1 - fy) * g[first] + fx * (1 - fy) * g[first + 1]
            + (1 - fx) * fy * g[first + W] + fx * fy * g[first + W + 1])


class _Views:
    """The views of one resolution with their cameras and distance images as torch tensors, and the data loss on
    them."""

    def __init__(self, views: list[_ViewData], silhouette: _Silhouette, kp_index: dict[str, int]) -> None:
        import torch

        self.views = views
        self.silhouette = silhouette
        self.kp_index = kp_index
        self.cams = [tuple(torch.tensor(m, dtype=torch.float32) for m in (v.K, v.R, v.t)) for v in views]
        height, width = max(v.height for v in views), max(v.width for v in views)
        # the frames padded to the largest with zeros, which read as the frame does
        self.outside = torch.stack([torch.nn.functional.pad(v.outside, (0, width - v.width, 0, height - v.height))
                                    for v in views])

    def loss(self, verts: "torch.Tensor", joints: "torch.Tensor", sigma: float) -> tuple["torch.Tensor", float]:
        """The data loss of a posed body (mean over the views; every term in full-resolution pixels) at silhouette
        edge width ``sigma`` (px of these images), and the mean silhouette IoU."""
        import torch

        # projections per view, the edge terms, then the vertices-inside term: the per-view loss's order, so that
        # autograd sums every gradient in the same order and the fit's arithmetic is that of the views one by one
        projected = [_project(verts, K, R, t) for K, R, t in self.cams]
        parts = [self.silhouette.pixels(v, uv.detach().double().numpy(), depth.detach().double().numpy(), sigma)
                 for v, (uv, depth) in zip(self.views, projected)]
        uv = torch.stack([uv for uv, _ in projected]).reshape(-1, 2)
        edge = _edge_terms(uv, parts, sigma)
        inside = self._inside(uv)
        total = torch.zeros((), dtype=verts.dtype)
        for k, (v, (K, R, t)) in enumerate(zip(self.views, self.cams)):
            f2 = float(v.scale * v.scale)
            sil, reach = edge[k]
            total = total + sigma * v.scale * sil + f2 * (inside[k] + REACH_WEIGHT * reach)
            if v.keypoints is not None:
                idx = torch.as_tensor([self.kp_index[n] for n in v.keypoints.names])
                juv, _ = _project(joints[idx], K, R, t)
                conf = torch.as_tensor(v.keypoints.confidence, dtype=verts.dtype)
                err = ((juv - torch.as_tensor(v.keypoints.xy / v.scale, dtype=verts.dtype)) ** 2).sum(-1)
                total = total + f2 * KEYPOINT_WEIGHT * (conf * err).sum() / conf.sum().clamp_min(1e-6)
        return total / len(self.views), float(np.mean([x.iou for x in parts]))

    def inside(self, verts: "torch.Tensor") -> "torch.Tensor":
        """The vertices-inside term alone (mean over the views, full-resolution pixels)."""
        import torch

        total = verts.sum() * 0.0
        for v, term in zip(self.views, self._inside(torch.cat([_project(verts, K, R, t)[0] for K, R, t in self.cams]))):
            total = total + v.scale * v.scale * term
        return total / len(self.views)

    def _inside(self, uv: "torch.Tensor") -> list["torch.Tensor"]:
        """Per view, the vertices-inside term (its pixels: the weighted mean squared distance outside the mask) of
        the projections ``uv`` (views x V, 2) px, view after view."""
        samples = _sample_outside(self.outside, uv).split(len(uv) // len(self.views))
        return [INSIDE_WEIGHT * (x ** 2).mean() for x in samples]


def _project(points: "torch.Tensor", K: "torch.Tensor", R: "torch.Tensor", t: "torch.Tensor"
             ) -> tuple["torch.Tensor", "torch.Tensor"]:
    """Pixel coordinates (N, 2) and camera depth (N,) of world points (metres) in the camera (K, R, t)."""
    pc = points @ R.T + t
    return (pc @ K.T)[:, :2] / pc[:, 2:3].clamp_min(1e-3), pc[:, 2]


def _rest_body(body: BodyModel, shape: dict[str, float], translation: np.ndarray | None = None) -> Any:
    """``body`` of ``shape`` at the rest pose moved by ``translation`` (metres; default none), without gradients."""
    import torch

    rest = torch.eye(3, dtype=torch.float32).expand(1, len(body.joint_names), 3, 3)
    move = torch.zeros(1, 3, dtype=torch.float32) if translation is None else torch.as_tensor(
        translation, dtype=torch.float32)[None]
    with torch.no_grad():
        return body.forward_torch({k: torch.tensor([x], dtype=torch.float32) for k, x in shape.items()}, rest, move)


def _start_search(body: BodyModel, shape: dict[str, float], views: _Views, sigma: float
                  ) -> tuple[dict[str, float], np.ndarray, list[tuple[float, float]]]:
    """The start shape and translation (metres): ``shape`` with :data:`START_PARAMETER` at the vertex of the
    parabola through the lowest of the data losses, at the rest pose placed on the masks, of :data:`START_VALUES`
    values and its two neighbours (the lowest itself when it is an end). Returns the shape, the translation and the
    (value, loss) pairs evaluated."""
    import torch

    def placed(value: float | None) -> tuple[dict[str, float], np.ndarray, "Any"]:
        trial = dict(shape) if value is None else {**shape, START_PARAMETER: value}
        out = _rest_body(body, trial)
        shift = _placed_translation(views.views, out.vertices[0].double().numpy(), views.silhouette)
        return trial, shift, out

    if START_PARAMETER not in shape:
        trial, shift, _ = placed(None)
        return trial, shift, []
    spec = body.parameters[START_PARAMETER]
    values = spec.low + (spec.high - spec.low) * (np.arange(START_VALUES) + 0.5) / START_VALUES
    losses = []
    for value in values:
        _, shift, out = placed(float(value))
        with torch.no_grad():
            move = torch.as_tensor(shift, dtype=torch.float32)
            losses.append(float(views.loss(out.vertices[0] + move, out.joints[0] + move, sigma)[0]))
    i = int(np.argmin(losses))
    best = float(values[i])
    if 0 < i < len(values) - 1:
        below, at, above = losses[i - 1], losses[i], losses[i + 1]
        curvature = below - 2.0 * at + above
        if curvature > 0:
            step = float(values[1] - values[0])
            best = float(np.clip(best - 0.5 * step * (above - below) / curvature, values[i - 1], values[i + 1]))
    trial, shift, _ = placed(best)
    return trial, shift, [(float(x), y) for x, y in zip(values, losses)]


def _stature(body: BodyModel, shape: dict[str, float]) -> float:
    """The vertical extent (metres) of ``body`` of ``shape`` at rest."""
    y = _rest_body(body, shape).vertices[0, :, 1]
    return float(y.max() - y.min())


def _alternative_starts(body: BodyModel, shape: dict[str, float]) -> list[dict[str, float]]:
    """``shape`` with :data:`START_ALTERNATIVES`' parameter at each of its values and :data:`START_PARAMETER` set so
    the body at rest is as tall as at ``shape`` (linear between the parameter's ends; ``shape`` itself where the
    value is its own); [``shape``] when the body model lacks either parameter."""
    name, values = START_ALTERNATIVES
    if name not in shape or START_PARAMETER not in shape:
        return [shape]
    spec = body.parameters[START_PARAMETER]
    target = _stature(body, shape)
    starts = []
    for value in values:
        if value == shape[name]:
            starts.append(dict(shape))
            continue
        low, high = (_stature(body, {**shape, name: value, START_PARAMETER: x}) for x in (spec.low, spec.high))
        x = spec.low + (spec.high - spec.low) * (target - low) / (high - low) if high != low else shape[
            START_PARAMETER]
        starts.append({**shape, name: value, START_PARAMETER: float(np.clip(x, spec.low, spec.high))})
    return starts


def _alternative_start(body: BodyModel, shape: dict[str, float], translation: np.ndarray, views: "_Views"
                       ) -> tuple[dict[str, float], list[tuple[float, float]]]:
    """Of :func:`_alternative_starts` of ``shape``, at rest moved by ``translation``, the one with the lowest
    vertices-inside term on ``views`` (a garment may hide body but the body may not leave the person's mask; the
    silhouette and reach terms, read at rest before the pose is fitted, favoured one gender under a loose dress);
    returns it and the (value, term) pairs."""
    import torch

    starts = _alternative_starts(body, shape)
    if len(starts) == 1:
        return shape, []
    scores = []
    for trial in starts:
        with torch.no_grad():
            scores.append(float(views.inside(_rest_body(body, trial, translation).vertices[0])))
    name = START_ALTERNATIVES[0]
    return starts[int(np.argmin(scores))], [(s[name], score) for s, score in zip(starts, scores)]


def fit_body(capture: Capture, body: BodyModel, settings: "BodyFitSettings", model_name: str,
             keypoints: Mapping[str, Keypoints] | None = None, reporter: Reporter | None = None,
             where: str = "capture") -> BodyFit:
    """Fit ``body``'s shape and pose to ``capture`` (silhouettes and labels; ``keypoints`` by view name, used when
    ``settings.keypoints``). ``where`` names the capture in errors."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # the fit's tensors are small: more threads only wait on each other
    try:
        return _fit(capture, body, settings, model_name, keypoints, reporter, where)
    finally:
        torch.set_num_threads(threads)


def _fit(capture: Capture, body: BodyModel, settings: "BodyFitSettings", model_name: str,
         keypoints: Mapping[str, Keypoints] | None, reporter: Reporter | None, where: str) -> BodyFit:
    import torch

    check_capture_layers(capture, where)
    reporter = reporter or Reporter.silent()
    start = time.perf_counter()
    chosen = spread_views([v.camera for v in capture.views], settings.views)
    use_kp = bool(settings.keypoints and keypoints)
    full = [_view_data(capture.views[i], (keypoints or {}).get(capture.views[i].camera.name) if use_kp else None)
            for i in chosen]
    names = body.joint_names
    kp_index = {n: i for i, n in enumerate(names)}
    for v in full:
        if v.keypoints is not None:
            unknown = sorted(set(v.keypoints.names) - set(kp_index))
            if unknown:
                raise PGCDataError(f"{where}: keypoints of view '{v.name}' name joints the body model "
                                   f"'{model_name}' lacks: {unknown[:5]}; its joints: {', '.join(names)}")
    silhouette = _Silhouette(np.asarray(body.faces))
    fine = _Views(full, silhouette, kp_index)
    coarse = _Views([_downsampled(v, coarse_factor(v.width, v.height)) for v in full], silhouette, kp_index)
    dtype = torch.float32
    params = body.parameters
    low = torch.tensor([params[k].low for k in params], dtype=dtype)
    high = torch.tensor([params[k].high for k in params], dtype=dtype)
    first = coarse if PHASES[0][2] else fine
    defaults = {k: params[k].default for k in params}
    shape0, start_shift, searched = _start_search(body, defaults, first, PHASES[0][1])
    chosen, alternatives = _alternative_start(body, shape0, start_shift, first)
    if chosen != shape0:  # another gender: its own height search (the stature found at the default one is off)
        name = START_ALTERNATIVES[0]
        shape0, start_shift, searched = _start_search(body, {**defaults, name: chosen[name]}, first, PHASES[0][1])
    frac = ((torch.tensor([shape0[k] for k in params], dtype=dtype) - low) / (high - low)).clamp(0.02, 0.98)
    shape_logit = torch.log(frac / (1 - frac)).clone().requires_grad_(True)
    angles = torch.zeros(len(names), 3, dtype=dtype, requires_grad=True)
    posed = torch.as_tensor(posed_joints(body))
    offset = torch.tensor(start_shift / TRANSLATION_SCALE, dtype=dtype, requires_grad=True)
    opt = torch.optim.Adam([shape_logit, angles, offset], lr=settings.learning_rate)

    def shape_of(logit: torch.Tensor) -> dict[str, torch.Tensor]:
        value = low + (high - low) * torch.sigmoid(logit)
        return {k: value[i:i + 1] for i, k in enumerate(params)}

    def pose() -> "Any":
        moving = torch.where(posed[:, None], angles, 0.0)
        return body.forward_torch(shape_of(shape_logit), _rodrigues(moving)[None], TRANSLATION_SCALE * offset[None])

    history: list[float] = []
    steps = 0
    iou = 0.0
    with reporter.stage("body_fit", total=settings.iterations, views=len(full), keypoints=use_kp) as st:
        for phase, (share, sigma, on_coarse) in enumerate(PHASES):
            views = coarse if on_coarse else fine
            n = max(1, int(round(share * settings.iterations)))
            last = phase == len(PHASES) - 1
            best, best_step = np.inf, 0
            for i in range(n):
                if last:
                    for g in opt.param_groups:
                        g["lr"] = settings.learning_rate * (0.1 ** (i / n))
                opt.zero_grad()
                out = pose()
                data, iou = views.loss(out.vertices[0], out.joints[0], sigma)
                loss = data + settings.pose_prior * 1e-3 * (angles ** 2).sum()
                loss.backward()
                opt.step()
                steps += 1
                history.append(float(loss.detach()))
                st.progress(steps, loss=history[-1], silhouette_iou=iou)
                if history[-1] < best:
                    best, best_step = history[-1], i
                elif i - best_step >= STALL_SHARE * n:
                    break
                if last and i >= 20 and history[-21] - history[-1] < settings.tolerance * abs(history[-21]):
                    break
    shape = {k: float(x) for k, x in zip(params, (low + (high - low) * torch.sigmoid(shape_logit)).tolist())}
    rotations = _rodrigues(torch.where(posed[:, None], angles.detach(), 0.0).double()).numpy()
    translation = (TRANSLATION_SCALE * offset.detach().double()).numpy()
    mesh = body.mesh(shape, rotations, translation)
    figures = {"views": len(full), "view_names": [v.name for v in full], "iterations": steps,
               "keypoints": use_kp, "loss": history[-1], "silhouette_iou": iou,
               "start_search": {"parameter": START_PARAMETER, "start": shape0[START_PARAMETER],
                                "tried": [list(pair) for pair in searched]} if searched else None,
               "start_alternatives": {"parameter": START_ALTERNATIVES[0], "start": shape0[START_ALTERNATIVES[0]],
                                      "tried": [list(pair) for pair in alternatives]} if alternatives else None,
               "seconds": round(time.perf_counter() - start, 3)}
    return BodyFit(model_name, dict(body.options.model_dump()), shape, tuple(names), rotations, translation, mesh,
                   figures)


UNDER_GARMENT_M = 0.1
"""A true body vertex is under the garment when the nearest garment vertex lies within this distance (metres)
and within 60 degrees of its outward normal."""


def vertex_error(vertices: np.ndarray, truth: Mesh, garment: Mesh | None = None) -> dict[str, Any]:
    """Distance of fitted body ``vertices`` (V, 3) to the true body, metres: per vertex when both share the
    topology (``kind`` 'per_vertex'), else of each fitted vertex to the true surface ('to_surface'); mean and
    max over all vertices, and separately over those under ``garment`` (:data:`UNDER_GARMENT_M`) and the rest."""
    from scipy.spatial import cKDTree

    vertices = np.asarray(vertices, np.float64)
    same = len(vertices) == len(truth.vertices)
    if same:
        dist = np.linalg.norm(vertices - truth.vertices, axis=1)
        owner = np.arange(len(vertices))
    else:
        from pgc.sim.collision import signed_distance

        dist = np.abs(signed_distance(vertices, truth.vertices, truth.faces))
        owner = cKDTree(truth.vertices).query(vertices)[1]
    under = np.zeros(len(vertices), bool)
    if garment is not None and len(garment.vertices):
        v, f = np.asarray(truth.vertices, np.float64), np.asarray(truth.faces)
        normals = np.zeros_like(v)
        fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        for k in range(3):
            np.add.at(normals, f[:, k], fn)
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        gap, nearest = cKDTree(garment.vertices).query(v)
        direction = (garment.vertices[nearest] - v) / np.maximum(gap, 1e-12)[:, None]
        covered = (gap < UNDER_GARMENT_M) & (np.einsum("ij,ij->i", direction, normals) > 0.5)
        under = covered[owner]

    def stats(d: np.ndarray) -> dict[str, float | int]:
        return {"mean": float(d.mean()) if len(d) else None, "max": float(d.max()) if len(d) else None,
                "vertices": int(len(d))}

    return {"kind": "per_vertex" if same else "to_surface", **stats(dist), "under_garment": stats(dist[under]),
            "exposed": stats(dist[~under])}
