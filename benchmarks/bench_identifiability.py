#!/usr/bin/env python
"""Which pgc-sheen parameters a capture's lighting identifies (the Jacobian study of pgc.brdfs.identifiability).

    python benchmarks/bench_identifiability.py [--fabrics cotton-sheen ...] [--noise 0.01] [--recover]
        [--out FILE.json]

For each in-family control fabric (its pgc-sheen truth, its texture colours on a sphere patch seen by 12
cameras) and each lighting ((a) uniform environment, (b) sky + sun, (c) uniform plus four known key-light
frames), the relative Jacobian of the pixels is taken (float64, forward-mode autodiff, checked against central
differences) over three parameter sets:
- ``all``: base-colour scale, light, roughness, sheen colour, sheen roughness (11): its exact null space;
- ``fit``: what the material fit optimises (light, roughness, sheen colour, sheen roughness; texture given);
- ``calibrated``: the light known (a light stage), base-colour scale free.
Printed per row: the smallest singular value (RMS pixel change per pixel for a unit relative change along
the weakest direction), the condition number, the weakest direction's largest loadings, and the relative
standard error of each pgc-sheen parameter for pixel noise ``--noise`` at an equal pixel budget (one frame's
pixels: the key-light capture's errors are scaled by sqrt(frames) so that more frames are not free).
``--recover``: each lighting's capture is also fitted (the fit's parameters, from the paper's initial values,
Levenberg-Marquardt on noisy pixels of a smaller patch) and each parameter's relative error printed.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

def parameter_sets() -> dict[str, tuple[str, ...]]:
    from pgc.brdfs.identifiability import FIT_PARAMETERS, PARAMETER_NAMES

    return {"all": PARAMETER_NAMES, "fit": FIT_PARAMETERS,
            "calibrated": PARAMETER_NAMES[:3] + PARAMETER_NAMES[6:]}


def fd_error(scene, frames, theta, J) -> float:
    """Largest |autodiff - central difference| over all columns, relative to the column's largest entry."""
    import torch

    from pgc.brdfs.identifiability import render

    worst = 0.0
    for i in range(len(theta)):
        h = 1e-6 * max(abs(theta[i]), 1e-3)
        e = np.zeros_like(theta)
        e[i] = h
        fd = (render(scene, frames, torch.tensor(theta + e)).numpy()
              - render(scene, frames, torch.tensor(theta - e)).numpy()) / (2 * h)
        worst = max(worst, float(np.abs(fd - J[:, i]).max() / max(np.abs(J[:, i]).max(), 1e-300)))
    return worst


def study(fabric_name: str, noise: float, n_points: int, n_dirs: int, check: bool) -> list[dict]:
    from pgc.brdfs import identifiability as ident
    from pgc.synth.fabrics import get_fabric

    fabric = get_fabric(fabric_name)
    p = fabric.params
    theta = ident.parameter_vector([1, 1, 1], [1, 1, 1], p["roughness"], p["sheen_color"], p["sheen_roughness"])
    scene = ident.study_scene(fabric.colors, n_points=n_points)
    rows = []
    for light_name, frames in ident.lightings(n_dirs).items():
        start = time.perf_counter()
        J = ident.jacobian(scene, frames, theta)
        row_fd = fd_error(scene, frames, theta, J) if check else None
        for set_name, names in parameter_sets().items():
            a = ident.analyse(J, theta, names, noise)
            budget = math.sqrt(len(frames))
            order = np.argsort(-np.abs(a.null_direction))[:4]
            rel = dict(zip(names, (a.relative_std * budget).tolist()))
            rows.append({
                "fabric": fabric_name, "light": light_name, "set": set_name, "frames": len(frames),
                "pixels": a.n_pixels, "sigma_min": float(a.singular_values[-1]),
                "sigma_max": float(a.singular_values[0]), "condition": a.condition,
                "null": {names[i]: round(float(a.null_direction[i]), 3) for i in order},
                "rel_std": rel, "fd_rel_error": row_fd, "seconds": time.perf_counter() - start})
    return rows


RECOVERY_LIGHT = (1.3, 1.1, 0.9)
"""The truth's light radiance in the recovery runs (the fit starts at 1, as the material fit does)."""
PAPER_START = {"roughness": 0.8, "sheen_color": (0.75, 0.73, 0.27), "sheen_roughness": 0.5}
"""The fit's initial values (pgc.brdfs.parameters, the paper's supplement)."""


def recovery(fabric_name: str, noise: float, n_points: int, n_dirs: int, iterations: int) -> list[dict]:
    """Levenberg-Marquardt from the paper's initial values on noisy pixels of the truth, per lighting:
    each fitted parameter's relative error."""
    from pgc.brdfs import identifiability as ident
    from pgc.synth.fabrics import get_fabric

    fabric = get_fabric(fabric_name)
    p = fabric.params
    truth = ident.parameter_vector([1, 1, 1], RECOVERY_LIGHT, p["roughness"], p["sheen_color"], p["sheen_roughness"])
    start = ident.parameter_vector([1, 1, 1], [1, 1, 1], PAPER_START["roughness"], PAPER_START["sheen_color"],
                                   PAPER_START["sheen_roughness"])
    scene = ident.study_scene(fabric.colors, n_points=n_points)
    rows = []
    for light_name, frames in ident.lightings(n_dirs).items():
        begin = time.perf_counter()
        fitted = ident.recover(scene, frames, truth, start, noise, iterations=iterations)
        err = {n: float(fitted[i] / truth[i] - 1.0) for i, n in enumerate(ident.PARAMETER_NAMES)
               if n in ident.FIT_PARAMETERS}
        rows.append({"fabric": fabric_name, "light": light_name, "pixels": len(frames) * len(scene.pairs[0]),
                     "fitted": dict(zip(ident.PARAMETER_NAMES, fitted.tolist())), "rel_error": err,
                     "max_abs_rel_error_brdf": max(abs(v) for k, v in err.items() if not k.startswith("light")),
                     "seconds": time.perf_counter() - begin})
    return rows


def print_recovery(rows: list[dict]) -> None:
    print(f"{'fabric':15s} {'light':15s} {'rough':>7s} {'sheen r/g/b':>23s} {'sheen_rough':>11s} {'light r/g/b':>23s}")
    for r in rows:
        e = r["rel_error"]
        trio = lambda k: "/".join(f"{100 * e[f'{k}_{c}']:+.1f}%" for c in "rgb")  # noqa: E731
        print(f"{r['fabric']:15s} {r['light']:15s} {100 * e['roughness']:+6.1f}% {trio('sheen'):>23s} "
              f"{100 * e['sheen_roughness']:+10.1f}% {trio('light'):>23s}")


def fmt_std(rel: dict, key: str) -> str:
    v = rel.get(key)
    return "-" if v is None else ("inf" if not math.isfinite(v) else f"{100 * v:.1f}%")


def print_table(rows: list[dict]) -> None:
    cols = ["fabric", "light", "set", "sigma_min", "cond", "weakest direction", "rough", "sheen rgb", "sheen_rough",
            "light rgb"]
    table = []
    for r in rows:
        rel = r["rel_std"]
        table.append({
            "fabric": r["fabric"], "light": r["light"], "set": r["set"], "sigma_min": f"{r['sigma_min']:.2e}",
            "cond": f"{r['condition']:.1e}",
            "weakest direction": " ".join(f"{k}{v:+.2f}" for k, v in r["null"].items()),
            "rough": fmt_std(rel, "roughness"),
            "sheen rgb": "/".join(fmt_std(rel, f"sheen_{c}") for c in "rgb"),
            "sheen_rough": fmt_std(rel, "sheen_roughness"),
            "light rgb": "/".join(fmt_std(rel, f"light_{c}") for c in "rgb")})
    widths = [max([len(c)] + [len(t[c]) for t in table]) for c in cols]
    print("  ".join(c.ljust(w) for c, w in zip(cols, widths)))
    for t in table:
        print("  ".join(t[c].ljust(w) for c, w in zip(cols, widths)))


def main() -> None:
    from pgc.synth.fabrics import FABRICS

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fabrics", nargs="+", default=[n for n in FABRICS if n.endswith("-sheen")])
    ap.add_argument("--noise", type=float, default=0.01, help="pixel noise std (linear radiance)")
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--dirs", type=int, default=256, help="environment directions")
    ap.add_argument("--no-check", action="store_true",
                    help="skip the finite-difference check (made on the first fabric)")
    ap.add_argument("--recover", action="store_true",
                    help="also fit each fabric from the paper's initial values (Levenberg-Marquardt, noisy pixels)")
    ap.add_argument("--recover-points", type=int, default=150)
    ap.add_argument("--recover-dirs", type=int, default=128)
    ap.add_argument("--recover-iterations", type=int, default=20)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    rows = [r for i, f in enumerate(args.fabrics)
            for r in study(f, args.noise, args.points, args.dirs, check=i == 0 and not args.no_check)]
    print_table(rows)
    checks = [r["fd_rel_error"] for r in rows if r["fd_rel_error"] is not None]
    if checks:
        print(f"finite-difference check: worst relative error {max(checks):.1e}")
    recovered = []
    if args.recover:
        recovered = [r for f in args.fabrics for r in recovery(f, args.noise, args.recover_points, args.recover_dirs,
                                                               args.recover_iterations)]
        print_recovery(recovered)
    if args.out:
        from pgc.io.atomic import write_json

        write_json(args.out, {"noise": args.noise, "points": args.points, "dirs": args.dirs, "rows": rows,
                              "recovery": recovered})


if __name__ == "__main__":
    main()
