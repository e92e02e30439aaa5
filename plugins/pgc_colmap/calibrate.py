"""The ``calibrator`` role on COLMAP: re-estimate the camera poses of a capture from its images with COLMAP (CPU).

Steps (pycolmap 4.2, CPU): SIFT ``extract_features`` with the capture's intrinsics written into the
database (PINHOLE), ``match_exhaustive``, ``incremental_mapping`` with focal length, principal point and
extra parameters fixed (free intrinsics on few views can converge to a wrong focal length). The largest
model's poses are brought into the capture's frame and scale by the similarity (Umeyama) that best maps
their camera centres onto the capture's; views COLMAP could not register keep their input pose.
"""

from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.roles.calibrator import Calibration, Calibrator
from pgc.types import Camera, Capture, View
from pgc_colmap.reconstruct import extract_and_match, quiet_colmap
from pgc_colmap.specs_calibrate import ColmapCalibratorOptions
from pgc_colmap.workspace import write_images


def umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Similarity (s, R, t) minimising sum |s R src + t - dst|^2 (Umeyama 1991); (N, 3) each, N >= 3."""
    mu_s, mu_d = src.mean(0), dst.mean(0)
    a, b = src - mu_s, dst - mu_d
    u, sig, vt = np.linalg.svd(b.T @ a / len(src))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    R = u @ d @ vt
    var = (a ** 2).sum() / len(src)
    s = float(np.trace(np.diag(sig) @ d) / var) if var > 0 else 1.0
    return s, R, mu_d - s * R @ mu_s


def _rotation_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1.0, 1.0))))


def _set_intrinsics(db_path: Path, cameras: dict[str, Camera]) -> None:
    """Write the capture's PINHOLE intrinsics into the database's cameras (as priors the mapper keeps)."""
    import pycolmap

    db = pycolmap.Database.open(str(db_path))
    try:
        for img in db.read_all_images():
            cam = db.read_camera(img.camera_id)
            c = cameras[img.name]
            cam.params = [c.fx, c.fy, c.K[0, 2], c.K[1, 2]]
            cam.has_prior_focal_length = True
            db.update_camera(cam)
    finally:
        db.close()


def calibrate(capture: Capture, max_features: int = 4096, peak_threshold: float = 0.002, min_inliers: int = 12,
              reporter: Reporter | None = None) -> tuple[Capture, dict[str, Any]]:
    """The capture with refined camera poses, and figures (registered views, reprojection error, pose
    changes: mean/max rotation in degrees and centre shift in metres)."""
    import pycolmap

    quiet_colmap()
    reporter = reporter or Reporter.silent()
    if len(capture.views) < 3:
        raise PGCDataError(f"calibration needs at least 3 views, the capture has {len(capture.views)}")
    with tempfile.TemporaryDirectory(prefix="pgc-calibrate-") as tmp, reporter.stage("calibrate"):
        root = Path(tmp)
        names = write_images(capture, root / "images")
        db_path = extract_and_match(capture, root, names, max_features, peak_threshold, min_inliers)
        ours = {n: v.camera for n, v in zip(names, capture.views)}
        _set_intrinsics(db_path, ours)
        opts = pycolmap.IncrementalPipelineOptions()
        # small images of cloth give few matches: accept smaller initial pairs and registrations
        opts.min_num_matches = 10
        opts.mapper.init_min_num_inliers = 30
        opts.mapper.abs_pose_min_num_inliers = 15
        opts.ba_refine_focal_length = False
        opts.ba_refine_principal_point = False
        opts.ba_refine_extra_params = False
        (root / "sparse").mkdir()
        models = pycolmap.incremental_mapping(db_path, root / "images", root / "sparse", options=opts)
    if not models:
        raise PGCDataError("COLMAP registered no views: the images have too few matching features "
                           "(textureless cloth, tiny images or too few overlapping views)")
    rec = max(models.values(), key=lambda r: r.num_reg_images())
    poses = {}
    for image in rec.images.values():
        if image.has_pose:
            m = image.cam_from_world().matrix()
            poses[image.name] = (np.asarray(m[:, :3]), np.asarray(m[:, 3]))
    if len(poses) < 3:
        raise PGCDataError(f"COLMAP registered only {len(poses)} views; at least 3 are needed to align them")
    reg = [n for n in names if n in poses]
    new_centres = np.stack([-poses[n][0].T @ poses[n][1] for n in reg])
    old_centres = np.stack([ours[n].center for n in reg])
    s, Rs, ts = umeyama(new_centres, old_centres)
    views: list[View] = []
    rot, shift = [], []
    for name, view in zip(names, capture.views):
        cam = view.camera
        if name in poses:
            R, t = poses[name]
            R2 = R @ Rs.T
            t2 = s * t - R2 @ ts
            new = replace(cam, R=R2, t=t2)
            rot.append(_rotation_deg(cam.R, R2))
            shift.append(float(np.linalg.norm(new.center - cam.center)))
            view = replace(view, camera=new)
        views.append(view)
    figures = {"registered_views": len(reg), "views": len(names),
               "reprojection_px": float(rec.compute_mean_reprojection_error()), "points": int(rec.num_points3D()),
               "rotation_change_deg_mean": float(np.mean(rot)), "rotation_change_deg_max": float(np.max(rot)),
               "centre_change_m_mean": float(np.mean(shift)), "centre_change_m_max": float(np.max(shift)),
               "similarity_scale": s}
    return replace(capture, views=views), figures


class ColmapCalibrator(Calibrator):
    Options = ColmapCalibratorOptions

    def calibrate(self, capture: Capture, reporter: Reporter | None = None) -> Calibration:
        opt = self.options
        refined, figures = calibrate(capture, opt.max_features, opt.sift_peak_threshold, opt.min_inliers, reporter)
        return Calibration(refined, figures)
