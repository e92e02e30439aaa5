"""The data model passed between roles. numpy arrays at every role boundary.

Conventions (docs/conventions.md):
- units: metres, seconds; world right-handed, +Y up;
- cameras: OpenCV (x right, y down, z forward), world-to-camera ``x_cam = R @ x_world + t``, pinhole ``K``;
  pixel centres at integer coordinates + 0.5 (pixel (0, 0) covers [0, 1) x [0, 1));
- images: float32 linear RGB in [0, 1], shape (H, W, 3); masks float32 in [0, 1], shape (H, W);
- UVs: (u, v) in [0, 1], v pointing up (OBJ/glTF-after-flip convention): texel row = (1 - v) * H;
- quaternions: (w, x, y, z).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pgc.errors import PGCDataError

BACKGROUND_LABEL = 0
"""Segmentation id of pixels that see no person."""
BODY_LABEL = 1
"""Segmentation id of the body (skin, and whatever is neither garment nor background)."""
GARMENT_LABEL = 2
"""Segmentation id of the garment in the default labels (:attr:`Capture.labels`; a capture may name more
garment ids) and in synthetic scenes."""
DEFAULT_LABELS = {BACKGROUND_LABEL: "background", BODY_LABEL: "body", GARMENT_LABEL: "garment"}
"""Segmentation id -> name of a capture that names none."""


def _check_finite(name: str, array: np.ndarray, where: str) -> None:
    if not np.all(np.isfinite(array)):
        bad = int(np.size(array) - np.count_nonzero(np.isfinite(array)))
        raise PGCDataError(f"{where}: field '{name}' has {bad} non-finite values (NaN or Inf); "
                           "fix or remove them before loading")


def _pixels(value: Any, name: str, where: str) -> int:
    """``value`` as an int if it is a whole number (``64`` or ``64.0``), else a PGCDataError: an image side is
    never truncated (``int(63.9)`` would be 63)."""
    whole = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)) \
        and math.isfinite(value) and float(value).is_integer()
    if not whole:
        raise PGCDataError(f"{where}: {name} must be a whole number of pixels, got {value!r}; give an integer")
    return int(value)


@dataclass
class Camera:
    """A calibrated pinhole camera (OpenCV convention), world-to-camera ``x_c = R x_w + t``."""

    K: np.ndarray
    """(3, 3) float64 intrinsics in pixels."""
    R: np.ndarray
    """(3, 3) float64 world-to-camera rotation."""
    t: np.ndarray
    """(3,) float64 world-to-camera translation (metres)."""
    width: int
    height: int
    name: str = ""
    dist: np.ndarray | None = None
    """Optional OpenCV distortion (k1, k2, p1, p2[, k3]); None means none. Rendering ignores it:
    importers undistort or reject distorted models."""

    def __post_init__(self) -> None:
        self.K = np.asarray(self.K, dtype=np.float64).reshape(3, 3)
        self.R = np.asarray(self.R, dtype=np.float64).reshape(3, 3)
        self.t = np.asarray(self.t, dtype=np.float64).reshape(3)
        where = f"camera '{self.name}'"
        self.width, self.height = _pixels(self.width, "width", where), _pixels(self.height, "height", where)
        for n in ("K", "R", "t"):
            _check_finite(n, getattr(self, n), where)
        if self.width <= 0 or self.height <= 0:
            raise PGCDataError(f"{where}: image size {self.width}x{self.height} must be positive")
        if abs(np.linalg.det(self.R) - 1.0) > 1e-4:
            raise PGCDataError(f"{where}: R is not a rotation (det = {np.linalg.det(self.R):.6f})")

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates, (3,)."""
        return -self.R.T @ self.t

    @property
    def world_to_camera(self) -> np.ndarray:
        """(4, 4) world-to-camera matrix."""
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = self.R, self.t
        return m

    @property
    def camera_to_world(self) -> np.ndarray:
        """(4, 4) camera-to-world matrix (OpenCV axes)."""
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = self.R.T, self.center
        return m

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points (N, 3) to pixel coordinates (N, 2) and camera depths z (N,)."""
        pc = np.asarray(points, dtype=np.float64) @ self.R.T + self.t
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = (pc @ self.K.T)[:, :2] / z[:, None]
        return uv, z

    def rays(self) -> tuple[np.ndarray, np.ndarray]:
        """World ray origins (H, W, 3) and unit directions (H, W, 3) through pixel centres."""
        ys, xs = np.mgrid[0:self.height, 0:self.width].astype(np.float64) + 0.5
        pix = np.stack([xs, ys, np.ones_like(xs)], axis=-1)
        d_cam = pix @ np.linalg.inv(self.K).T
        d_world = d_cam @ self.R
        d_world /= np.linalg.norm(d_world, axis=-1, keepdims=True)
        return np.broadcast_to(self.center, d_world.shape).copy(), d_world

    def cropped(self, x0: int, y0: int, width: int, height: int) -> "Camera":
        """The sub-image of ``width`` x ``height`` pixels whose top-left pixel is (``x0``, ``y0``)."""
        K = self.K.copy()
        K[0, 2] -= x0
        K[1, 2] -= y0
        return replace(self, K=K, width=int(width), height=int(height))

    def scaled(self, factor: float) -> "Camera":
        """The same camera at ``factor`` times the resolution (intrinsics scaled about the corner)."""
        K = self.K.copy()
        K[:2] *= factor
        return replace(self, K=K, width=max(1, round(self.width * factor)),
                       height=max(1, round(self.height * factor)))


def look_at_pose(eye: np.ndarray, target: np.ndarray, up: tuple[float, float, float] = (0.0, 1.0, 0.0)
                 ) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV world-to-camera (R, t) of a camera at ``eye`` looking at ``target`` (metres) with world ``up`` up
    (world +Z stands in for ``up`` when the camera looks along it)."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    if np.linalg.norm(x) < 1e-8:
        x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)  # image down
    R = np.stack([x, y, z])
    return R, -R @ np.asarray(eye, float)


@dataclass
class View:
    """One calibrated image of the capture."""

    camera: Camera
    image: np.ndarray
    """(H, W, 3) float32 linear RGB."""
    mask: np.ndarray | None = None
    """(H, W) float32 foreground in [0, 1]."""
    segmentation: np.ndarray | None = None
    """(H, W) uint8 label ids (see Capture.labels); 0 is background."""
    background: np.ndarray | None = None
    """(H, W, 3) float32 linear RGB image of the empty scene."""
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    """Optional ground-truth layers by name (e.g. 'albedo' (H, W, 3), 'depth' (H, W) metres along z)."""

    def __post_init__(self) -> None:
        h, w = self.camera.height, self.camera.width
        where = f"view '{self.camera.name}'"
        self.image = np.asarray(self.image, dtype=np.float32)
        if self.image.shape != (h, w, 3):
            raise PGCDataError(f"{where}: image shape {self.image.shape} does not match the camera "
                               f"size (H, W, 3) = {(h, w, 3)}")
        if self.mask is not None:
            self.mask = np.asarray(self.mask, dtype=np.float32)
            if self.mask.shape != (h, w):
                raise PGCDataError(f"{where}: mask shape {self.mask.shape} != {(h, w)}")
        if self.segmentation is not None:
            self.segmentation = np.asarray(self.segmentation, dtype=np.uint8)
            if self.segmentation.shape != (h, w):
                raise PGCDataError(f"{where}: segmentation shape {self.segmentation.shape} != {(h, w)}")
        if self.background is not None:
            self.background = np.asarray(self.background, dtype=np.float32)
            if self.background.shape != (h, w, 3):
                raise PGCDataError(f"{where}: background shape {self.background.shape} != {(h, w, 3)}")


@dataclass
class Light:
    """Scene lighting: a constant environment of RGB radiance, optionally times an environment map."""

    radiance: np.ndarray = field(default_factory=lambda: np.ones(3))
    """(3,) RGB radiance scale (W sr^-1 m^-2, relative units)."""
    envmap: np.ndarray | None = None
    """Optional (H, 2H, 3) float32 latitude-longitude map, +Y up, u=0 at -Z going through +X
    (Mitsuba's convention after its y-up transform); multiplied by ``radiance``."""
    rotation_deg: float = 0.0
    """Rotation of the environment about +Y, degrees."""

    def __post_init__(self) -> None:
        self.radiance = np.asarray(self.radiance, dtype=np.float64).reshape(3)


@dataclass
class Capture:
    """A multi-view capture of one static frame."""

    views: list[View]
    labels: dict[int, str] = field(default_factory=lambda: dict(DEFAULT_LABELS))
    """Segmentation id -> name. Ids whose name is neither 'background' nor 'body' are garments."""
    light: Light | None = None
    """Known lighting, when the capture provides it (synthetic ground truth)."""
    metadata: dict[str, Any] = field(default_factory=dict)
    root: str | None = None
    """Directory the capture was read from, if any."""

    def __post_init__(self) -> None:
        if not self.views:
            raise PGCDataError("capture has no views")
        names = [v.camera.name for v in self.views]
        if len(set(names)) != len(names):
            raise PGCDataError("capture: camera names must be unique")

    @property
    def cameras(self) -> list[Camera]:
        return [v.camera for v in self.views]

    @property
    def garment_label_ids(self) -> list[int]:
        return sorted(i for i, n in self.labels.items() if n not in ("background", "body"))


@dataclass
class Mesh:
    """A triangle mesh with optional UV atlas and per-face labels."""

    vertices: np.ndarray
    """(V, 3) float64 positions (metres)."""
    faces: np.ndarray
    """(F, 3) int64 vertex indices, counter-clockwise seen from outside."""
    uv: np.ndarray | None = None
    """(T, 2) float32 texture coordinates in [0, 1], v up."""
    face_uv: np.ndarray | None = None
    """(F, 3) int64 indices into ``uv`` (UV seams split texture vertices, not positions)."""
    face_labels: np.ndarray | None = None
    """(F,) int32 segmentation ids (Capture.labels)."""
    name: str = ""

    def __post_init__(self) -> None:
        where = f"mesh '{self.name}'" if self.name else "mesh"
        self.vertices = np.asarray(self.vertices, dtype=np.float64)
        self.faces = np.asarray(self.faces, dtype=np.int64)
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            raise PGCDataError(f"{where}: vertices must have shape (V, 3), got {self.vertices.shape}")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise PGCDataError(f"{where}: faces must have shape (F, 3), got {self.faces.shape}")
        _check_finite("vertices", self.vertices, where)
        if self.faces.size and (self.faces.min() < 0 or self.faces.max() >= len(self.vertices)):
            raise PGCDataError(f"{where}: face indices out of range [0, {len(self.vertices)})")
        if (self.uv is None) != (self.face_uv is None):
            raise PGCDataError(f"{where}: uv and face_uv must be given together")
        if self.uv is not None:
            self.uv = np.asarray(self.uv, dtype=np.float32)
            self.face_uv = np.asarray(self.face_uv, dtype=np.int64)
            _check_finite("uv", self.uv, where)
            if self.face_uv.shape != self.faces.shape:
                raise PGCDataError(f"{where}: face_uv shape {self.face_uv.shape} != faces {self.faces.shape}")
            if self.face_uv.size and (self.face_uv.min() < 0 or self.face_uv.max() >= len(self.uv)):
                raise PGCDataError(f"{where}: face_uv indices out of range [0, {len(self.uv)})")
        if self.face_labels is not None:
            self.face_labels = np.asarray(self.face_labels, dtype=np.int32)
            if self.face_labels.shape != (len(self.faces),):
                raise PGCDataError(f"{where}: face_labels shape {self.face_labels.shape} != ({len(self.faces)},)")

    def face_normals(self) -> np.ndarray:
        """(F, 3) unit face normals; zero for degenerate faces."""
        v = self.vertices[self.faces]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.divide(n, length, out=np.zeros_like(n), where=length > 0)

    def face_areas(self) -> np.ndarray:
        v = self.vertices[self.faces]
        return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)

    def vertex_normals(self) -> np.ndarray:
        """(V, 3) area-weighted unit vertex normals."""
        v = self.vertices[self.faces]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        out = np.zeros_like(self.vertices)
        for k in range(3):
            np.add.at(out, self.faces[:, k], n)
        length = np.linalg.norm(out, axis=1, keepdims=True)
        return np.divide(out, length, out=np.zeros_like(out), where=length > 0)

    def edges(self) -> np.ndarray:
        """(E, 2) unique undirected edges, sorted vertex pairs."""
        e = np.concatenate([self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]])
        return np.unique(np.sort(e, axis=1), axis=0)

    def submesh(self, face_mask: np.ndarray, name: str = "") -> tuple["Mesh", np.ndarray]:
        """The faces selected by ``face_mask`` with unused vertices dropped.

        Returns the new mesh and (V_new,) indices of its vertices in this mesh.
        """
        faces = self.faces[np.asarray(face_mask, dtype=bool)]
        used = np.unique(faces)
        remap = np.full(len(self.vertices), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        uv = face_uv = None
        if self.uv is not None:
            fuv = self.face_uv[np.asarray(face_mask, dtype=bool)]
            used_uv = np.unique(fuv)
            remap_uv = np.full(len(self.uv), -1, dtype=np.int64)
            remap_uv[used_uv] = np.arange(len(used_uv))
            uv, face_uv = self.uv[used_uv], remap_uv[fuv]
        labels = None if self.face_labels is None else self.face_labels[np.asarray(face_mask, dtype=bool)]
        return Mesh(self.vertices[used], remap[faces], uv, face_uv, labels, name or self.name), used


@dataclass
class GaussianSet:
    """Mesh-embedded 3D Gaussians (GaussianAvatars binding, docs/method.md section 2).

    Each Gaussian lives in the local frame of its parent triangle: origin the centroid, rotation
    columns [normalised edge (v1 - v0), normal, edge x normal], scale k = (base + height) / 2.
    World parameters: ``r' = R r``, ``mu' = k R mu + tau``, ``s' = k s``.
    """

    parent: np.ndarray
    """(N,) int64 parent face index."""
    means: np.ndarray
    """(N, 3) float32 local positions."""
    quats: np.ndarray
    """(N, 4) float32 local rotations, (w, x, y, z), not necessarily normalised."""
    log_scales: np.ndarray
    """(N, 3) float32 natural log of local scales."""
    opacity_logits: np.ndarray
    """(N,) float32 logit of opacity."""
    sh: np.ndarray
    """(N, (D+1)^2, 3) float32 real SH coefficients per colour channel (3DGS convention:
    colour = SH . basis + 0.5, clamped at 0); index 0 is the DC term."""

    def __post_init__(self) -> None:
        n = len(self.parent)
        self.parent = np.asarray(self.parent, dtype=np.int64)
        self.means = np.asarray(self.means, dtype=np.float32).reshape(n, 3)
        self.quats = np.asarray(self.quats, dtype=np.float32).reshape(n, 4)
        self.log_scales = np.asarray(self.log_scales, dtype=np.float32).reshape(n, 3)
        self.opacity_logits = np.asarray(self.opacity_logits, dtype=np.float32).reshape(n)
        self.sh = np.asarray(self.sh, dtype=np.float32)
        if self.sh.ndim != 3 or self.sh.shape[0] != n or self.sh.shape[2] != 3:
            raise PGCDataError(f"gaussians: sh must have shape (N, K, 3) with N={n}, got {self.sh.shape}")
        k = self.sh.shape[1]
        if round(np.sqrt(k)) ** 2 != k or k > 16:
            raise PGCDataError(f"gaussians: {k} SH coefficients is not (D+1)^2 for a degree D <= 3")
        for name in ("means", "quats", "log_scales", "opacity_logits", "sh"):
            _check_finite(name, getattr(self, name), "gaussians")

    def __len__(self) -> int:
        return len(self.parent)

    @property
    def sh_degree(self) -> int:
        return int(round(np.sqrt(self.sh.shape[1]))) - 1

    def select(self, keep: np.ndarray) -> "GaussianSet":
        """The Gaussians where ``keep`` (bool mask or index array) holds."""
        return GaussianSet(self.parent[keep], self.means[keep], self.quats[keep], self.log_scales[keep],
                           self.opacity_logits[keep], self.sh[keep])


@dataclass
class WorldGaussians:
    """Gaussians in world space, as a splat renderer consumes them (activated parameters)."""

    means: np.ndarray
    """(N, 3) world positions."""
    quats: np.ndarray
    """(N, 4) rotations (w, x, y, z), normalised by the renderer."""
    scales: np.ndarray
    """(N, 3) standard deviations along the rotated axes (metres)."""
    opacities: np.ndarray
    """(N,) in [0, 1]."""
    sh: np.ndarray
    """(N, K, 3) SH coefficients, as in GaussianSet."""


@dataclass
class Material:
    """A BRDF choice with its parameters and the base-colour texture."""

    brdf: str
    """Name of the brdf implementation ('lambertian', 'disney', 'pgc-sheen', ...)."""
    params: dict[str, float | list[float]] = field(default_factory=dict)
    """Constant (spatially uniform) parameters by name; colours as 3-lists (linear RGB)."""
    base_color: np.ndarray | None = None
    """(H, W, 3) float32 linear RGB albedo texture over the mesh UV atlas, or None (use params)."""


@dataclass
class BodyMotion:
    """An animated body mesh: vertices per frame with fixed topology."""

    vertices: np.ndarray
    """(T, V, 3) float32 positions per frame (metres)."""
    faces: np.ndarray
    """(F, 3) int64."""
    fps: float = 30.0
    name: str = ""

    def __post_init__(self) -> None:
        self.vertices = np.asarray(self.vertices, dtype=np.float32)
        self.faces = np.asarray(self.faces, dtype=np.int64)
        if self.vertices.ndim != 3 or self.vertices.shape[2] != 3:
            raise PGCDataError(f"motion '{self.name}': vertices must be (T, V, 3), got {self.vertices.shape}")
        _check_finite("vertices", self.vertices, f"motion '{self.name}'")
        if not (isinstance(self.fps, numbers.Real) and math.isfinite(self.fps) and self.fps > 0):
            raise PGCDataError(f"motion '{self.name}': fps must be a finite positive number (frames per second), "
                               f"got {self.fps!r}")

    @property
    def num_frames(self) -> int:
        return int(self.vertices.shape[0])

    def frame_mesh(self, t: int) -> Mesh:
        return Mesh(self.vertices[t], self.faces, name=f"{self.name}[{t}]")


@dataclass
class GarmentAsset:
    """A simulation-ready, relightable garment: the output of `pgc reconstruct`."""

    garment: Mesh
    """The garment sub-mesh (rest shape for simulation) with UVs."""
    body: Mesh
    """The full reconstructed body+garment mesh of the capture pose (labels per face)."""
    gaussians: GaussianSet
    """Gaussians bound to ``garment`` faces."""
    material: Material
    light: Light
    """The fitted capture lighting."""
    heldout_views: list[str] = field(default_factory=list)
    """Names of the capture views the splat fit held out (the render stage chooses its kernel on them)."""
    config: dict[str, Any] = field(default_factory=dict)
    """The resolved run configuration that produced the asset."""
    figures: dict[str, Any] = field(default_factory=dict)
    """Measured figures of each stage (timings, errors)."""
