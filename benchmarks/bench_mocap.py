"""Captured motion clips: parse time, the motion round-trip error, and garment penetration on the shipped CMU
clips (docs/simulation.md, "Captured motion").

    python benchmarks/bench_mocap.py [--out DIR] [--resolution 0.03] [--simulator xpbd-native] [--no-sim]
                                     [--arm-space DEG] [--name bench_mocap]

Round trip: each AMC retargeted onto a rig built from its ASF's own skeleton, joint positions against the
Acclaim forward kinematics of the ASF/AMC (``pgc.motion.asf.bone_end_positions``); and each clip written as BVH
and read back. Penetration: the synthetic t-shirt (``--resolution`` metre edges) simulated at the simulator's
default settings (the paper's: 30 fps, 30 substeps, 20 iterations) on the synthetic body driven by each clip;
the fraction of garment vertices deeper than the collision offset inside the body, per frame. Writes
``NAME.json`` (``bench_mocap_no_arm_space.json`` is the run with ``--arm-space 0``).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from pgc.io.asset import package_versions

CLIPS = ("02_01", "02_03", "02_04", "02_05")


def best_of(fn, repeats: int = 3) -> tuple[float, object]:
    best, value = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        value = fn()
        best = min(best, time.perf_counter() - start)
    return best, value


def round_trips() -> list[dict]:
    from pgc.motion.asf import amc_clip, bone_end_positions, read_amc, read_asf
    from pgc.motion.bvh import read_bvh, write_bvh
    from pgc.motion.drive import shipped_clips
    from pgc.motion.retarget import Rig, retarget

    records = []
    folder = shipped_clips()
    for name in CLIPS:
        seconds, clip = best_of(lambda: amc_clip(asf := read_asf(folder / "02.asf"),
                                                 read_amc(folder / f"{name}.amc", asf)))
        asf = read_asf(folder / "02.asf")
        amc = read_amc(folder / f"{name}.amc", asf)
        sk = clip.skeleton
        rig = Rig(sk.names, sk.parents, sk.rest_positions())
        pos = retarget(clip, rig, {n: n for n in sk.names}).joint_positions(rig)
        ends = bone_end_positions(asf, amc)
        err = np.concatenate([np.linalg.norm(
            pos[:, sk.index(asf.children[b][0] if asf.children.get(b) else f"{b}_end")] - ends[b], axis=-1)
            for b in asf.order()])
        with tempfile.TemporaryDirectory() as tmp:
            write_bvh(Path(tmp) / "c.bvh", clip)
            bvh_seconds, back = best_of(lambda: read_bvh(Path(tmp) / "c.bvh"))
        order = [back.skeleton.index(n) for n in sk.names]
        bvh_err = np.linalg.norm(back.joint_positions()[:, order] - clip.joint_positions(), axis=-1)
        records.append({"clip": name, "frames": clip.num_frames, "parse_amc_s": seconds, "parse_bvh_s": bvh_seconds,
                        "round_trip_max_m": float(err.max()), "round_trip_mean_m": float(err.mean()),
                        "bvh_round_trip_max_m": float(bvh_err.max()), "bvh_round_trip_mean_m": float(bvh_err.mean())})
        print(records[-1], flush=True)
    return records


def penetration(resolution: float, simulator: str, arm_space: float | None) -> list[dict]:
    from pgc.config import load
    from pgc.events import Reporter
    from pgc.motion.drive import clip_body_motion, shipped_clips
    from pgc.synth.body import make_body
    from pgc.synth.garments import make_garment

    body = make_body(load().create("body_model"))
    cloth = make_garment(body, "tshirt", resolution=resolution)
    from pgc.config import resolve

    cfg = resolve({"simulator": {"use": [simulator]}}, None, source="bench_mocap")
    records = []
    for name in CLIPS:
        start = time.perf_counter()
        motion = clip_body_motion(shipped_clips() / f"{name}.amc", body, arm_space_deg=arm_space)
        drive_s = time.perf_counter() - start
        start = time.perf_counter()
        out = cfg.create("simulator").simulate(cloth, motion, Reporter.silent())
        sim_s = time.perf_counter() - start
        pen = np.asarray(out.figures["penetration_fraction"])
        records.append({"clip": name, "frames": motion.num_frames, "garment_vertices": len(cloth.vertices),
                        "body_vertices": len(body.vertices), "simulator": cfg.roles["simulator"].name,
                        "arm_space_deg": arm_space,
                        "retarget_and_skin_s": drive_s, "simulate_s": sim_s,
                        "penetration_max": float(pen.max()), "penetration_mean": float(pen.mean()),
                        "frames_with_penetration": int(np.count_nonzero(pen > 0)),
                        "p99_stretch_strain_max": float(max(out.figures["p99_stretch_strain"])),
                        "finite": bool(np.all(np.isfinite(out.vertices)))})
        print(records[-1], flush=True)
    return records


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="benchmarks/results")
    parser.add_argument("--resolution", type=float, default=0.03)
    parser.add_argument("--simulator", default="xpbd-native")
    parser.add_argument("--no-sim", action="store_true", help="skip the penetration study")
    parser.add_argument("--arm-space", type=float, default=None,
                        help="degrees (pgc.motion.retarget.keep_arms_clear; default: its own; 0: arms as captured)")
    parser.add_argument("--name", default="bench_mocap", help="name of the JSON file written")
    args = parser.parse_args()
    result = {"round_trip": round_trips(), "versions": package_versions()}
    if not args.no_sim:
        result["penetration"] = penetration(args.resolution, args.simulator, args.arm_space)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{args.name}.json").write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
