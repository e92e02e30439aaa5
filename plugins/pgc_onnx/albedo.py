"""ONNX albedo estimator: runs an intrinsic-decomposition network with onnxruntime on the CPU.

Model contract (version 1; docs/albedo.md):
- one input, float32, shape (N, 3, H, W); H and W multiples of the metadata value ``pgc_multiple_of``
  (default 16); values in ``pgc_input_space`` ("srgb", the default, or "linear"), in [0, 1];
- an output named ``albedo`` of the same shape, in ``pgc_output_space`` (default "srgb"), in [0, 1];
  an output ``shading`` is optional and ignored here;
- optional metadata ``pgc_tile`` / ``pgc_overlap``: the tile size and overlap for large images.
Images larger than a tile are processed in overlapping tiles blended with a linear ramp, which equals a
whole-image run away from tile borders when the receptive field is within the overlap.
"""

from __future__ import annotations

import hashlib
from importlib import resources
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.io.images import linear_to_srgb, srgb_to_linear
from pgc.roles.albedo_estimator import AlbedoEstimator
from pgc_onnx.specs_albedo import OnnxAlbedoOptions

SHIPPED_MODEL = "albedo_unet.onnx"


def shipped_model_path() -> Path:
    return Path(str(resources.files("pgc_onnx") / "models" / SHIPPED_MODEL))


class OnnxAlbedoEstimator(AlbedoEstimator):
    Options = OnnxAlbedoOptions

    def __init__(self, options: OnnxAlbedoOptions | dict | None = None) -> None:
        super().__init__(options)
        import onnxruntime as ort

        path = Path(self.options.model) if self.options.model else shipped_model_path()
        if not path.is_file():
            raise PGCDataError(f"albedo model '{path}' not found; set [albedo_estimator.onnx] model = \"...\" to "
                               "an ONNX file, or retrain the shipped one with scripts/train_albedo.py")
        so = ort.SessionOptions()
        so.intra_op_num_threads = self.options.threads
        so.inter_op_num_threads = 1
        try:
            self.session = ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])
        except Exception as exc:
            raise PGCDataError(f"albedo model '{path}' is not a loadable ONNX model: {exc}") from None
        self.path = path
        self.fingerprint = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
        """Content hash of the model file (pipeline caches key on it)."""
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            raise PGCDataError(f"albedo model '{path}': expected one input (N, 3, H, W), found {len(inputs)}")
        shape, dtype = inputs[0].shape, inputs[0].type
        if len(shape) != 4 or shape[1] != 3 or dtype != "tensor(float)":
            raise PGCDataError(f"albedo model '{path}': input '{inputs[0].name}' is {dtype} of shape {shape}; "
                               "the contract needs float32 (N, 3, H, W)")
        outputs = [o.name for o in self.session.get_outputs()]
        if "albedo" not in outputs:
            raise PGCDataError(f"albedo model '{path}': no output named 'albedo' (outputs: {outputs})")
        meta = self.session.get_modelmeta().custom_metadata_map
        self.input_name = inputs[0].name
        self.multiple_of = int(meta.get("pgc_multiple_of", 16))
        self.input_space = meta.get("pgc_input_space", "srgb")
        self.output_space = meta.get("pgc_output_space", "srgb")
        self.tile = int(self.options.tile or meta.get("pgc_tile", 256))
        self.overlap = int(self.options.overlap if self.options.overlap is not None else meta.get("pgc_overlap", 32))
        if self.tile % self.multiple_of or self.tile <= 2 * self.overlap:
            raise PGCDataError(f"albedo model '{path}': tile {self.tile} must be a multiple of {self.multiple_of} "
                               f"and larger than twice the overlap {self.overlap}")

    def estimate(self, image: np.ndarray, mask: np.ndarray | None = None,
                 shading: np.ndarray | None = None) -> np.ndarray:
        image = np.asarray(image, dtype=np.float32)
        if image.ndim != 3 or image.shape[2] != 3:
            raise PGCDataError(f"albedo estimator: image must be (H, W, 3), got {image.shape}")
        x = np.clip(image, 0.0, 1.0)
        x = linear_to_srgb(x) if self.input_space == "srgb" else x
        out = self._run_tiled(np.nan_to_num(x).astype(np.float32))
        out = np.clip(out, 0.0, 1.0)
        out = srgb_to_linear(out) if self.output_space == "srgb" else out
        if self.options.shading_kernel:
            out = smooth_shading(np.nan_to_num(np.clip(image, 0.0, 1.0)), out, mask, self.options.shading_kernel)
        return out.astype(np.float32)

    def run_whole(self, x: np.ndarray) -> np.ndarray:
        """The network on a whole (H, W, 3) image in its input space (padded to the multiple)."""
        h, w = x.shape[:2]
        m = self.multiple_of
        ph, pw = -h % m, -w % m
        xp = np.pad(x, ((0, ph), (0, pw), (0, 0)), mode="reflect" if min(h, w) > max(ph, pw) else "edge")
        y = self.session.run(["albedo"], {self.input_name: xp.transpose(2, 0, 1)[None]})[0][0]
        return y.transpose(1, 2, 0)[:h, :w]

    def _run_tiled(self, x: np.ndarray) -> np.ndarray:
        h, w = x.shape[:2]
        t, o = self.tile, self.overlap
        if h <= t and w <= t:
            return self.run_whole(x)
        step = t - 2 * o
        acc = np.zeros((h, w, 3), np.float64)
        wsum = np.zeros((h, w), np.float64)
        for y0 in _starts(h, t, step):
            for x0 in _starts(w, t, step):
                tile = x[y0:y0 + t, x0:x0 + t]
                pred = self.run_whole(tile)
                wy = _ramp(tile.shape[0], o, y0 == 0, y0 + t >= h)
                wx = _ramp(tile.shape[1], o, x0 == 0, x0 + t >= w)
                weight = wy[:, None] * wx[None, :]
                acc[y0:y0 + t, x0:x0 + t] += pred * weight[..., None]
                wsum[y0:y0 + t, x0:x0 + t] += weight
        return (acc / np.maximum(wsum, 1e-12)[..., None]).astype(np.float32)


def smooth_shading(image: np.ndarray, albedo: np.ndarray, mask: np.ndarray | None, kernel_size: int,
                   floor: float = 1e-3) -> np.ndarray:
    """Albedo = image / low-pass(image / albedo): the implied shading (linear, per channel) is blurred with the
    mask-aware Gaussian (weights = ``mask`` where the albedo exceeds ``floor``), so only its low frequencies
    come from the network. Where the albedo or the smoothed shading vanish the result stays finite (clipped
    to [0, 1])."""
    from pgc.filtering.kernel import odd_size
    from pgc.filtering.reference import lowpass_separable

    albedo = np.asarray(albedo, np.float64)
    trusted = albedo.mean(axis=-1) > floor
    weight = trusted if mask is None else trusted & (np.asarray(mask) > 0.5)
    shading = np.where(trusted[..., None], image / np.maximum(albedo, floor), 0.0)
    smooth = lowpass_separable(shading, weight.astype(np.float32), odd_size(kernel_size))
    out = np.where(weight[..., None], image / np.maximum(smooth, floor), albedo)
    return np.clip(np.nan_to_num(out, nan=0.0, posinf=1.0), 0.0, 1.0)


def _starts(n: int, tile: int, step: int) -> list[int]:
    if n <= tile:
        return [0]
    starts = list(range(0, n - tile, step))
    return starts + [n - tile]


def _ramp(n: int, overlap: int, first: bool, last: bool) -> np.ndarray:
    """Weights along one tile axis: zero over the outer ``overlap / 2`` pixels (the network's border zone),
    then a linear ramp over ``overlap`` pixels; neighbouring tiles (stride ``tile - 2 overlap``) ramp in
    complementary fashion. No ramp at the image's own borders."""
    idx = np.arange(n, dtype=np.float64) + 0.5
    w = np.ones(n)
    if overlap > 0:
        if not first:
            w = np.minimum(w, np.clip((idx - overlap / 2) / overlap, 0.0, 1.0))
        if not last:
            w = np.minimum(w, np.clip((n - idx - overlap / 2) / overlap, 0.0, 1.0))
    return np.maximum(w, 1e-6)
