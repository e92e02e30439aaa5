"""The ``smplx`` body model: SMPL from the user's licensed model file, posed with the ``smplx`` package.

The file (option ``model_path``) holds SMPL's arrays: ``v_template`` (V, 3), ``shapedirs`` (V, 3, S),
``posedirs`` (V, 3, 9 (J - 1)), ``J_regressor`` (J, V), ``weights`` (V, J), ``kintree_table`` (2, J) and ``f``
(F, 3), as a pickle (the official ``SMPL_*.pkl`` once cleared of chumpy objects) or an ``.npz``. Pickles are read
with an unpickler that builds numpy and scipy.sparse objects only. SMPL's frame is PGC's (Y-up, facing +Z).
Posed vertices include SMPL's pose-corrective blend shapes; the transforms are the rigid joint transforms.
"""

from __future__ import annotations

import functools
import io
import pickle
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from pgc.builtin_plugins.specs_body import SmplxOptions
from pgc.errors import PGCDataError
from pgc.roles.body_model import BodyModel, BodyTensors, ShapeParameter, global_transforms_torch

if TYPE_CHECKING:
    import torch

SMPL_KEYS = ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table", "f")
FIX = ("set [body_model.smplx] model_path to SMPL's model file (SMPL_NEUTRAL.pkl from smpl.is.tue.mpg.de, "
       "cleared of chumpy objects, or its arrays in an .npz)")


class _ArraysOnly(pickle.Unpickler):
    """Unpickles numpy arrays and scipy sparse matrices, nothing else."""

    SAFE = {("_codecs", "encode"), ("copy_reg", "_reconstructor"), ("copyreg", "_reconstructor")}
    """Helpers that protocol-2 pickles of numpy arrays use (bytes and plain object reconstruction)."""

    def find_class(self, module: str, name: str) -> Any:
        if module.split(".")[0] == "numpy" or module.startswith("scipy.sparse") or (module, name) in self.SAFE:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"{module}.{name}" + (" (a chumpy object: convert the file to plain numpy "
                                                           "arrays)" if module.startswith("chumpy") else ""))


def read_smpl_file(path: str | Path) -> dict[str, np.ndarray]:
    """SMPL's arrays from ``path`` (.pkl or .npz), checked for keys, shapes and finiteness."""
    path = Path(path).expanduser()
    where = f"body_model 'smplx': model_path {str(path)!r}"
    if not path.is_file():
        raise PGCDataError(f"{where} is not a file; {FIX}")
    try:
        if path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as npz:
                raw = {k: npz[k] for k in npz.files}
        else:
            raw = _ArraysOnly(io.BytesIO(path.read_bytes()), encoding="latin1").load()
    except Exception as exc:  # any unreadable file: one message naming the option
        raise PGCDataError(f"{where} is not an SMPL model file ({type(exc).__name__}: {exc}); {FIX}") from None
    if not isinstance(raw, Mapping):
        raise PGCDataError(f"{where} holds a {type(raw).__name__}, not SMPL's table of arrays; {FIX}")
    missing = [k for k in SMPL_KEYS if k not in raw]
    if missing:
        raise PGCDataError(f"{where} lacks {missing} (an SMPL model file has {', '.join(SMPL_KEYS)}); {FIX}")
    data = {k: np.asarray(raw[k].toarray() if hasattr(raw[k], "toarray") else raw[k]) for k in SMPL_KEYS}
    V, J = len(data["v_template"]), data["weights"].shape[-1]
    expected = {"v_template": (V, 3), "shapedirs": (V, 3, None), "posedirs": (V, 3, 9 * (J - 1)),
                "J_regressor": (J, V), "weights": (V, J), "kintree_table": (2, J), "f": (None, 3)}
    for key, shape in expected.items():
        got = data[key].shape
        if len(got) != len(shape) or any(s is not None and s != g for s, g in zip(shape, got)):
            raise PGCDataError(f"{where}: '{key}' has shape {got}, expected {shape} (None: any); {FIX}")
        if not np.all(np.isfinite(data[key])):
            raise PGCDataError(f"{where}: '{key}' holds NaN or infinite values; {FIX}")
    if data["f"].min() < 0 or data["f"].max() >= V:
        raise PGCDataError(f"{where}: face indices 'f' outside [0, {V}); {FIX}")
    parents = data["kintree_table"][0].astype(np.int64)
    if np.any(parents[1:] >= np.arange(1, J)) or np.any(parents[1:] < 0):
        raise PGCDataError(f"{where}: 'kintree_table' must list each joint's parent before it; {FIX}")
    return data


@functools.lru_cache(maxsize=4)
def load_smpl(path: str, num_betas: int, dtype_name: str = "float32"):
    """smplx's SMPL module for the file at ``path`` (cached per process and dtype)."""
    import contextlib

    import smplx
    import torch

    data = read_smpl_file(path)
    with contextlib.redirect_stdout(io.StringIO()):  # smplx prints a warning for fewer than 300 betas
        return smplx.SMPL(path, data_struct=smplx.utils.Struct(**data), num_betas=num_betas,
                          dtype=getattr(torch, dtype_name))


class SmplBody(BodyModel):
    """SMPL's body from the user's licensed model file; shape parameters ``beta0`` .. ``beta{n-1}``."""

    Options = SmplxOptions

    def __init__(self, options: SmplxOptions | dict | None = None) -> None:
        super().__init__(options)
        self._smpl = load_smpl(str(Path(self.options.model_path).expanduser().resolve()), self.options.num_betas)
        r = self.options.beta_range
        self.parameters = {f"beta{i}": ShapeParameter(-r, r, 0.0, f"SMPL shape coefficient {i} (standard "
                                                                     "deviations)")
                           for i in range(self._smpl.num_betas)}

    @functools.cached_property
    def joint_names(self) -> tuple[str, ...]:
        from smplx.joint_names import JOINT_NAMES, SMPLH_JOINT_NAMES

        names = {24: JOINT_NAMES[:22] + ["left_hand", "right_hand"], 52: SMPLH_JOINT_NAMES[:52],
                 55: JOINT_NAMES[:55]}  # SMPL, SMPL+H, SMPL-X
        J = len(self.parents)
        return tuple(names.get(J, [f"joint{j}" for j in range(J)]))

    @functools.cached_property
    def parents(self) -> np.ndarray:
        parents = self._smpl.parents.cpu().numpy().astype(np.int64)
        parents[0] = -1
        return parents

    @functools.cached_property
    def faces(self) -> np.ndarray:
        return np.asarray(self._smpl.faces, dtype=np.int64)

    @functools.cached_property
    def weights(self) -> np.ndarray:
        return self._smpl.lbs_weights.cpu().numpy().astype(np.float64)

    def forward_torch(self, shape: Mapping[str, "torch.Tensor"], rotations: "torch.Tensor",
                      translation: "torch.Tensor") -> BodyTensors:
        import torch
        from smplx.lbs import blend_shapes, lbs, vertices2joints

        dtype = rotations.dtype
        smpl = load_smpl(str(Path(self.options.model_path).expanduser().resolve()), self.options.num_betas,
                         str(dtype).removeprefix("torch."))
        betas = torch.stack([shape[k].to(dtype) for k in self.parameters], dim=1).expand(len(rotations), -1)
        rest = smpl.v_template + blend_shapes(betas, smpl.shapedirs)
        rest_joints = vertices2joints(smpl.J_regressor, rest)
        ground = torch.stack([-rest_joints[:, 0, 0], -rest[..., 1].min(dim=1).values, -rest_joints[:, 0, 2]], dim=1)
        vertices, joints = lbs(betas, rotations, smpl.v_template, smpl.shapedirs, smpl.posedirs, smpl.J_regressor,
                               smpl.parents, smpl.lbs_weights, pose2rot=False)
        offset = (ground + translation)[:, None]
        transforms = global_transforms_torch(rest_joints + ground[:, None], self.parents, rotations, translation)
        return BodyTensors(vertices + offset, joints + offset, transforms)
