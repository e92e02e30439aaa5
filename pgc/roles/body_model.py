"""Role ``body_model``: a parametric human body: shape parameters and a pose -> a rigged, skinned mesh.

Contract
- Frame (docs/conventions.md): metres, +Y up, the person faces +Z, their left is +X. In the rest pose
  (every local rotation the identity, no translation) the lowest vertex lies on y = 0 and the root joint on
  x = z = 0, for every shape.
- Shape: a mapping name -> float over :attr:`BodyModel.parameters` (each with its range and default; a name
  left out takes its default). :meth:`BodyModel.check_shape` rejects unknown names, non-numbers, non-finite and
  out-of-range values with one :class:`pgc.errors.PGCDataError` naming the parameter and its range.
- Rig: :meth:`BodyModel.rig` -> joint names, parents (-1 for the root; parents come before their children)
  and rest joint positions (J, 3) for a shape. The joint set is the implementation's (``anny``: the CMU
  motion-capture skeleton; ``smplx``: SMPL's 24, SMPL+H's 52 or SMPL-X's 55 joints);
  :attr:`BodyModel.joint_names` lists it. :attr:`BodyModel.weights` (V, J): the linear-blend-skinning weights,
  non-negative up to round-off (1e-9), rows summing to 1.
- Pose: ``rotations`` (..., J, 3, 3) local rotations in the world-aligned axes of the rest pose, each about its
  joint's rest position (identity = rest pose; ``global_j = global_parent @ local_j``; :func:`global_transforms`
  in numpy, :func:`global_transforms_torch` in torch), and ``translation`` (..., 3) metres added to every point.
- :meth:`BodyModel.forward` -> :class:`BodyState`: vertices (V, 3), joints (J, 3) and skinning transforms
  (J, 4, 4) (rest point -> posed point) in float64, and the faces (F, 3) int64, counter-clockwise seen from
  outside. :meth:`BodyModel.skin` poses a clip: (T, J, 3, 3) and (T, 3) -> (T, V, 3) float32.
- Differentiable: :meth:`BodyModel.forward_torch` takes torch tensors (shape values (B,) or (1,) for one shape
  over the batch, rotations (B, J, 3, 3), translation (B, 3)) and returns tensors in the rotations' dtype
  (float32 or float64) with gradients with respect to all three.
"""

from __future__ import annotations

import math
import numbers
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

import numpy as np

from pgc.errors import PGCDataError
from pgc.roles._base import RoleImplementation

if TYPE_CHECKING:
    import torch


@dataclass(frozen=True)
class ShapeParameter:
    """One shape parameter: its range, default and meaning."""

    low: float
    high: float
    default: float
    description: str


@dataclass(frozen=True)
class Rig:
    """A body's skeleton at rest."""

    names: tuple[str, ...]
    parents: np.ndarray
    """(J,) int64 parent index, -1 for the root."""
    joints: np.ndarray
    """(J, 3) float64 rest positions, metres."""


@dataclass(frozen=True)
class BodyState:
    """A posed body (numpy, float64)."""

    vertices: np.ndarray
    """(V, 3) positions, metres."""
    faces: np.ndarray
    """(F, 3) int64, counter-clockwise seen from outside."""
    joints: np.ndarray
    """(J, 3) posed joint positions."""
    transforms: np.ndarray
    """(J, 4, 4) skinning transforms: rest point -> posed point, per joint."""


@dataclass(frozen=True)
class BodyTensors:
    """A posed batch of bodies (torch, differentiable)."""

    vertices: "torch.Tensor"
    """(B, V, 3)."""
    joints: "torch.Tensor"
    """(B, J, 3)."""
    transforms: "torch.Tensor"
    """(B, J, 4, 4)."""


class BodyModel(RoleImplementation, ABC):
    role = "body_model"
    parameters: ClassVar[Mapping[str, ShapeParameter]] = {}
    """Shape parameter name -> its range and default."""

    @property
    @abstractmethod
    def joint_names(self) -> tuple[str, ...]:
        """Names of the J joints, in the order of the rotations."""

    @property
    @abstractmethod
    def parents(self) -> np.ndarray:
        """(J,) int64 parent index of each joint, -1 for the root."""

    @property
    @abstractmethod
    def faces(self) -> np.ndarray:
        """(F, 3) int64 triangles, counter-clockwise seen from outside."""

    @property
    @abstractmethod
    def weights(self) -> np.ndarray:
        """(V, J) float64 skinning weights, non-negative up to round-off, each row summing to 1."""

    @abstractmethod
    def forward_torch(self, shape: Mapping[str, "torch.Tensor"], rotations: "torch.Tensor",
                      translation: "torch.Tensor") -> BodyTensors:
        """Pose a batch: ``shape`` name -> (B,) or (1,) tensor (every parameter given, checked by the caller),
        ``rotations`` (B, J, 3, 3), ``translation`` (B, 3), all of one dtype; differentiable."""

    def check_shape(self, shape: Mapping[str, Any] | None) -> dict[str, float]:
        """``shape`` completed with the defaults, after checking names, types and ranges."""
        shape = dict(shape or {})
        unknown = sorted(set(shape) - set(self.parameters))
        if unknown:
            raise PGCDataError(f"body_model '{type(self).__name__}': unknown shape parameter(s) {unknown}; "
                               f"parameters: {', '.join(self.parameters)}")
        values = {}
        for name, spec in self.parameters.items():
            value = shape.get(name, spec.default)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
                raise PGCDataError(f"body_model shape parameter '{name}' must be a finite number in "
                                   f"[{spec.low}, {spec.high}], got {value!r}")
            if not spec.low <= value <= spec.high:
                raise PGCDataError(f"body_model shape parameter '{name}' = {value} is outside its range "
                                   f"[{spec.low}, {spec.high}] ({spec.description})")
            values[name] = float(value)
        return values

    def forward(self, shape: Mapping[str, Any] | None = None, rotations: np.ndarray | None = None,
                translation: np.ndarray | None = None) -> BodyState:
        """The body of ``shape`` posed by ``rotations`` (J, 3, 3) and ``translation`` (3,) (both optional)."""
        rotations, translation = self._check_pose(rotations, translation, batch=())
        out = self._run(self.check_shape(shape), rotations[None], translation[None])
        return BodyState(out.vertices[0].numpy(), self.faces.copy(), out.joints[0].numpy(), out.transforms[0].numpy())

    def rig(self, shape: Mapping[str, Any] | None = None) -> Rig:
        """Joint names, parents and rest joint positions of ``shape``."""
        return Rig(self.joint_names, self.parents.copy(), self.forward(shape).joints)

    def skin(self, shape: Mapping[str, Any] | None, rotations: np.ndarray, translation: np.ndarray | None = None,
             chunk: int = 64) -> np.ndarray:
        """A clip: rotations (T, J, 3, 3) and translation (T, 3) -> vertices (T, V, 3) float32."""
        rotations = np.asarray(rotations, dtype=np.float64)
        if rotations.ndim != 4 or len(rotations) == 0:
            raise PGCDataError(f"body_model.skin: rotations must be (T, J, 3, 3) with T >= 1, got "
                               f"{rotations.shape}")
        rotations, translation = self._check_pose(rotations, translation, batch=(len(rotations),))
        values = self.check_shape(shape)
        return np.concatenate([self._run(values, rotations[start:start + chunk], translation[start:start + chunk])
                               .vertices.numpy().astype(np.float32) for start in range(0, len(rotations), chunk)])

    def mesh(self, shape: Mapping[str, Any] | None = None, rotations: np.ndarray | None = None,
             translation: np.ndarray | None = None):
        """The posed body as a :class:`pgc.types.Mesh` named 'body' (label 1 on every face)."""
        from pgc.types import Mesh

        state = self.forward(shape, rotations, translation)
        return Mesh(state.vertices, state.faces, face_labels=np.ones(len(state.faces), np.int32), name="body")

    def _check_pose(self, rotations: np.ndarray | None, translation: np.ndarray | None,
                    batch: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        J = len(self.joint_names)
        if rotations is None:
            rotations = np.broadcast_to(np.eye(3), batch + (J, 3, 3))
        rotations = np.asarray(rotations, dtype=np.float64)
        if rotations.shape != batch + (J, 3, 3):
            raise PGCDataError(f"body_model: rotations must have shape {batch + (J, 3, 3)} (one 3x3 rotation per "
                               f"joint of {', '.join(self.joint_names[:3])}, ...), got {rotations.shape}")
        translation = np.zeros(batch + (3,)) if translation is None else np.asarray(translation, np.float64)
        if translation.shape != batch + (3,):
            raise PGCDataError(f"body_model: translation must have shape {batch + (3,)}, got {translation.shape}")
        for name, a in (("rotations", rotations), ("translation", translation)):
            if not np.all(np.isfinite(a)):
                raise PGCDataError(f"body_model: {name} hold NaN or infinite values")
        gram = np.einsum("...ji,...jk->...ik", rotations, rotations)
        if np.max(np.abs(gram - np.eye(3)), initial=0.0) > 1e-4 or np.min(np.linalg.det(rotations), initial=1) < 0:
            raise PGCDataError("body_model: rotations must be proper rotation matrices (orthonormal, det +1)")
        return rotations, translation

    def _run(self, values: dict[str, float], rotations: np.ndarray, translation: np.ndarray) -> BodyTensors:
        import torch

        with torch.no_grad():
            shape = {k: torch.full((1,), v, dtype=torch.float64) for k, v in values.items()}
            out = self.forward_torch(shape, torch.from_numpy(np.ascontiguousarray(rotations)),
                                     torch.from_numpy(np.ascontiguousarray(translation)))
        return BodyTensors(out.vertices.double(), out.joints.double(), out.transforms.double())


def global_transforms_torch(joints: "torch.Tensor", parents: np.ndarray, rotations: "torch.Tensor",
                            translation: "torch.Tensor") -> "torch.Tensor":
    """Skinning transforms (B, J, 4, 4) of the role's pose convention (torch, differentiable).

    ``joints`` (B, J, 3) rest positions, ``rotations`` (B, J, 3, 3) local world-aligned rotations about each
    joint (parents before children), ``translation`` (B, 3) added to every point."""
    import torch

    rot_g: list[torch.Tensor] = []
    pos_g: list[torch.Tensor] = []
    for j, p in enumerate(parents.tolist()):
        if p < 0:
            rot_g.append(rotations[:, j])
            pos_g.append(joints[:, j] + translation)
        else:
            rot_g.append(rot_g[p] @ rotations[:, j])
            pos_g.append(pos_g[p] + (rot_g[p] @ (joints[:, j] - joints[:, p])[..., None])[..., 0])
    R = torch.stack(rot_g, dim=1)
    t = torch.stack(pos_g, dim=1) - (R @ joints[..., None])[..., 0]
    top = torch.cat([R, t[..., None]], dim=-1)
    bottom = torch.zeros_like(top[..., :1, :])
    bottom[..., 0, 3] = 1.0
    return torch.cat([top, bottom], dim=-2)


def global_transforms(joints: np.ndarray, parents: np.ndarray, rotations: np.ndarray,
                      translation: np.ndarray | None = None) -> np.ndarray:
    """Skinning transforms (..., J, 4, 4) of the role's pose convention (numpy, float64): ``joints`` (J, 3) rest
    positions, ``rotations`` (..., J, 3, 3) local world-aligned rotations about each joint (parents first),
    ``translation`` (..., 3) metres added to every point (default none)."""
    rotations = np.asarray(rotations, dtype=np.float64)
    J = len(parents)
    if rotations.shape[-3:] != (J, 3, 3):
        raise PGCDataError(f"joint rotations must have shape (..., {J}, 3, 3), got {rotations.shape}")
    batch = rotations.shape[:-3]
    shift = np.zeros(batch + (3,)) if translation is None else np.broadcast_to(translation, batch + (3,))
    rot_g = np.empty_like(rotations)
    pos_g = np.empty(batch + (J, 3))
    for j, p in enumerate(np.asarray(parents).tolist()):
        if p < 0:
            rot_g[..., j, :, :] = rotations[..., j, :, :]
            pos_g[..., j, :] = joints[j] + shift
        else:
            rot_g[..., j, :, :] = rot_g[..., p, :, :] @ rotations[..., j, :, :]
            pos_g[..., j, :] = pos_g[..., p, :] + np.einsum("...ab,b->...a", rot_g[..., p, :, :], joints[j] - joints[p])
    out = np.zeros(batch + (J, 4, 4))
    out[..., :3, :3] = rot_g
    out[..., :3, 3] = pos_g - np.einsum("...jab,jb->...ja", rot_g, joints)
    out[..., 3, 3] = 1.0
    return out
