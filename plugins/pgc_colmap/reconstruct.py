"""The ``colmap`` reconstructor: what pycolmap does on a CPU, with our depth maps where it needs CUDA.

Steps that run in COLMAP here (pycolmap 4.2, CPU):
1. ``extract_features`` (SIFT, CPU) and ``match_exhaustive`` (CPU) on the capture images;
2. ``triangulate_points`` with the known cameras (poses and intrinsics fixed): sparse points that tell
   fusion which views overlap and whose
   reprojection error checks the calibration (figures ``sparse_points``, ``sparse_reprojection_px``);
3. ``stereo_fusion`` of depth and normal maps written in COLMAP's format into a dense workspace. COLMAP's
   own ``patch_match_stereo`` needs CUDA, so the maps come from PGC's hull-guided plane sweep
   (pgc.geometry.stereo);
4. ``poisson_meshing`` (COLMAP's screened Poisson, ``trim`` = 0 by default);
then PGC trims the surface by the visual hull and runs the shared finishing steps.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from pgc.errors import PGCDataError
from pgc.events import Reporter
from pgc.geometry.dense import dense_points, hull_fill_points, poisson_depth_for, trim_outside
from pgc.geometry.finish import finish
from pgc.geometry.hull import _axis_centre
from pgc.geometry.stereo import depth_normals, select_neighbours
from pgc.roles.reconstructor import Reconstruction, Reconstructor
from pgc.types import Capture
from pgc_colmap.specs_reconstruct import ColmapReconstructorOptions
from pgc_colmap.workspace import write_dense_array, write_images


def quiet_colmap() -> None:
    """Keep COLMAP's glog INFO lines out of the console (warnings and errors still show)."""
    import pycolmap

    pycolmap.logging.minloglevel = 1


def known_model(capture: Capture, database: Path, names: list[str]) -> Any:
    """A pycolmap reconstruction of the database's rigs, cameras, frames and images with the capture's
    intrinsics and poses (each image its own trivial rig, so rig_from_world = cam_from_world)."""
    import pycolmap

    ours = {name: view.camera for name, view in zip(names, capture.views)}
    db = pycolmap.Database.open(str(database))
    try:
        rigs, cams, frames, images = db.read_all_rigs(), db.read_all_cameras(), db.read_all_frames(), db.read_all_images()
    finally:
        db.close()
    image_of_camera = {img.camera_id: img for img in images}
    image_of_frame = {img.frame_id: img for img in images}
    rec = pycolmap.Reconstruction()
    for cam in cams:
        c = ours[image_of_camera[cam.camera_id].name]
        cam.params = [c.fx, c.fy, c.K[0, 2], c.K[1, 2]]
        rec.add_camera(cam)
    for rig in rigs:
        rec.add_rig(rig)
    for frame in frames:
        c = ours[image_of_frame[frame.frame_id].name]
        frame.rig_from_world = pycolmap.Rigid3d(pycolmap.Rotation3d(c.R), c.t)
        rec.add_frame(frame)
    for img in images:
        rec.add_image(img)
    for frame in frames:
        rec.register_frame(frame.frame_id)
    return rec


def extract_and_match(capture: Capture, root: Path, names: list[str], max_features: int, peak_threshold: float,
                      min_inliers: int) -> Path:
    """SIFT features of ``root/images/<names>`` (one PINHOLE camera per image) and exhaustive, verified
    matches, on the CPU, into ``root/database.db`` (returned)."""
    import pycolmap

    quiet_colmap()
    db = root / "database.db"
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.max_image_size = max(max(v.camera.width, v.camera.height) for v in capture.views)
    extraction.sift.max_num_features = int(max_features)
    extraction.sift.peak_threshold = float(peak_threshold)
    pycolmap.extract_features(db, root / "images", image_names=names, camera_mode=pycolmap.CameraMode.PER_IMAGE,
                              reader_options=reader, extraction_options=extraction, device=pycolmap.Device.cpu)
    verification = pycolmap.TwoViewGeometryOptions()
    verification.min_num_inliers = int(min_inliers)
    pycolmap.match_exhaustive(db, verification_options=verification, device=pycolmap.Device.cpu)
    return db


def sparse_triangulation(capture: Capture, root: Path, names: list[str], max_features: int = 4096,
                         peak_threshold: float = 0.002, min_inliers: int = 15) -> tuple[Any, dict[str, float]]:
    """SIFT + exhaustive matching + triangulation with the known poses (nothing refined). Returns the
    pycolmap reconstruction and figures. A low SIFT ``peak_threshold`` finds features on low-contrast
    cloth (COLMAP's default, 0.0067, finds few on small images)."""
    import pycolmap

    db = extract_and_match(capture, root, names, max_features, peak_threshold, min_inliers)
    images = root / "images"
    known = known_model(capture, db, names)
    out = root / "triangulated"
    out.mkdir(exist_ok=True)
    rec = pycolmap.triangulate_points(known, db, images, out, refine_intrinsics=False)
    figures = {"sparse_points": int(rec.num_points3D()),
               "sparse_reprojection_px": float(rec.compute_mean_reprojection_error()) if rec.num_points3D() else float("nan"),
               "sparse_track_length": float(rec.compute_mean_track_length()) if rec.num_points3D() else 0.0}
    return rec, figures


def fuse_depth_maps(capture: Capture, depths: list[np.ndarray], root: Path, names: list[str],
                    opt: ColmapReconstructorOptions, sparse: Any) -> Path:
    """Write a COLMAP dense workspace (the triangulated ``sparse`` model, whose shared points tell fusion
    which images overlap, plus our depth/normal maps) and run ``stereo_fusion``; returns fused.ply."""
    import pycolmap

    quiet_colmap()
    dense = root / "dense"
    write_images(capture, dense / "images")
    (dense / "sparse").mkdir(parents=True, exist_ok=True)
    sparse.write(str(dense / "sparse"))
    for sub in ("depth_maps", "normal_maps", "consistency_graphs"):
        (dense / "stereo" / sub).mkdir(parents=True, exist_ok=True)
    for view, depth, name in zip(capture.views, depths, names):
        _, normals, ok = depth_normals(view.camera, depth)
        d = np.where(ok, depth, 0.0)
        write_dense_array(dense / "stereo" / "depth_maps" / f"{name}.geometric.bin", d)
        write_dense_array(dense / "stereo" / "normal_maps" / f"{name}.geometric.bin", normals)
    (dense / "stereo" / "fusion.cfg").write_text("\n".join(names) + "\n")
    # Source images per reference image: the stereo neighbours (COLMAP's "__auto__" needs sparse points).
    centre = _axis_centre(capture.cameras)
    lines = []
    for i, name in enumerate(names):
        nbrs = select_neighbours(capture.cameras, i, opt.neighbours, centre)
        lines.append(f"{name}\n{', '.join(names[j] for j in nbrs)}\n")
    (dense / "stereo" / "patch-match.cfg").write_text("".join(lines))
    fo = pycolmap.StereoFusionOptions()
    fo.min_num_pixels = int(opt.fusion_min_pixels)
    fo.max_reproj_error = float(opt.fusion_max_reproj_error)
    fo.max_depth_error = float(opt.fusion_max_depth_error)
    fo.max_normal_error = float(opt.fusion_max_normal_error)
    fused = root / "fused.ply"
    pycolmap.stereo_fusion(fused, dense, input_type="geometric", options=fo, output_type="PLY")
    return fused


def add_hull_points(fused: Path, dense: Any, opt: ColmapReconstructorOptions) -> tuple[int, int]:
    """Rewrite COLMAP's fused point cloud (x y z nx ny nz) with the visual hull's points added where fusion
    found nothing (``hull_fill``); returns (fused, added) point counts."""
    import trimesh

    cloud = trimesh.load(fused, file_type="ply", process=False)
    raw = cloud.metadata["_ply_raw"]["vertex"]["data"]
    pts = np.stack([raw["x"], raw["y"], raw["z"]], 1).astype(np.float64)
    nrm = np.stack([raw["nx"], raw["ny"], raw["nz"]], 1).astype(np.float64)
    hp, hn = hull_fill_points(dense.hull, pts, dense.footprint) if opt.hull_fill else (np.zeros((0, 3)), np.zeros((0, 3)))
    data = np.concatenate([np.concatenate([pts, hp]), np.concatenate([nrm, hn])], 1).astype("<f4")
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(data)}\n"
              + "".join(f"property float {n}\n" for n in ("x", "y", "z", "nx", "ny", "nz")) + "end_header\n")
    with open(fused, "wb") as f:
        f.write(header.encode())
        data.tofile(f)
    return len(pts), len(hp)


class ColmapReconstructor(Reconstructor):
    Options = ColmapReconstructorOptions

    def reconstruct(self, capture: Capture, reporter: Reporter | None = None) -> Reconstruction:
        import pycolmap

        from pgc.io.mesh import read_mesh

        opt = self.options
        reporter = reporter or Reporter.silent()
        figures: dict[str, Any] = {}
        t0 = time.perf_counter()
        # COLMAP's fusion takes a depth map of every image
        dense = dense_points(capture, opt.model_copy(update={"hull_fill": False, "stereo_views": 0}), reporter)
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory(prefix="pgc-colmap-") as tmp:
            root = Path(tmp)
            names = write_images(capture, root / "images")
            with reporter.stage("mesh.colmap_sparse"):
                sparse, sparse_figures = sparse_triangulation(capture, root, names, opt.max_features,
                                                              opt.sift_peak_threshold, opt.min_inliers)
            figures.update(sparse_figures)
            if sparse_figures["sparse_points"] == 0:
                raise PGCDataError("COLMAP triangulated no points from the capture images with the given cameras: "
                                   "check the camera poses and that the images have texture")
            t2 = time.perf_counter()
            with reporter.stage("mesh.colmap_fusion"):
                fused = fuse_depth_maps(capture, dense.depths, root, names, opt, sparse)
            t3 = time.perf_counter()
            with reporter.stage("mesh.colmap_poisson"):
                po = pycolmap.PoissonMeshingOptions()
                po.trim = float(opt.poisson_trim)
                # the extent of what is meshed: the stereo points, or the hull when stereo found none
                extent_points = dense.points if len(dense.points) else dense.hull.vertices
                po.depth = int(opt.poisson_depth or poisson_depth_for(extent_points,
                                                                      opt.poisson_cell_px * dense.footprint))
                meshed = root / "meshed.ply"
                figures["fused_points"], figures["hull_points"] = add_hull_points(fused, dense, opt)
                pycolmap.poisson_meshing(fused, meshed, po)
                if not meshed.is_file():
                    raise PGCDataError("COLMAP's Poisson meshing produced no mesh (too few fused points: check the "
                                       "masks, the camera poses and the image texture)")
                raw = read_mesh(meshed)
                v, f = trim_outside(raw.vertices, raw.faces, dense.field(raw.vertices) <= opt.hull_margin_px * dense.footprint)
            t4 = time.perf_counter()
        mesh, fin = finish(v, f, capture.views, capture.labels, opt, reporter, name="colmap")
        figures.update(fin)
        figures.update(seconds_dense=t1 - t0, seconds_colmap_sparse=t2 - t1, seconds_colmap_fusion=t3 - t2,
                       seconds_colmap_poisson=t4 - t3, poisson_depth=po.depth, stereo_points=dense.stereo_points)
        return Reconstruction(mesh, figures)
