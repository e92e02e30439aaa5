"""Acclaim ASF (skeleton) and AMC (motion) files, as the CMU motion capture database ships them.

ASF sections: ``:units`` (``mass``, ``length``, ``angle deg|rad``), ``:root`` (``order`` of the root's
channels, ``axis`` order, rest ``position`` and ``orientation``), ``:bonedata`` (per bone: ``id``, ``name``,
unit ``direction`` in world axes, ``length``, ``axis`` angles and their order, ``dof`` and ``limits``) and
``:hierarchy`` (parent followed by its children). AMC: optional header lines, then per frame its number and
one line per bone with the values of its degrees of freedom in the ASF's order (angles in the ASF's unit).

Lengths: CMU's ``length 0.45`` means one file unit is 1/0.45 inch, so metres = value x 0.0254 / length (its
femurs come out at 0.40-0.43 m). Rotations: a bone's frame is ``C`` = the ``axis`` angles composed in the
listed order (first listed applied first); its motion ``M`` = the dof rotations composed the same way; its
global rotation is ``G = G_parent @ C @ M @ C^-1``, and its end lies ``length x G @ direction`` past its start
(the parent's end; the root's position for the root's children).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.io import limits
from pgc.motion.clip import Clip, Skeleton
from pgc.motion.rotations import euler_to_matrix

INCH_M = 0.0254
MAX_CLIP_BYTES = 512 << 20
"""Largest ASF, AMC or BVH file read (bytes): the longest CMU clip (2 minutes at 120 fps) is about 15 MB."""
HEIGHT_RANGE_M = (0.5, 2.6)
"""Extent (metres) of a rest skeleton accepted as a person; outside it the length unit is wrong."""
CMU_FPS = 120.0
"""Frame rate of CMU's AMC files (AMC carries no rate; CMU captured at 120 frames per second)."""
_ROTATION_DOFS = {"rx": "X", "ry": "Y", "rz": "Z"}
_TRANSLATION_DOFS = ("tx", "ty", "tz")


@dataclass(frozen=True)
class Bone:
    name: str
    direction: np.ndarray
    """(3,) unit direction from the bone's start to its end in world axes (rest pose)."""
    length: float
    """Metres."""
    axis: np.ndarray
    """(3, 3) rotation C of the bone's local frame."""
    dof: tuple[str, ...]
    """Degrees of freedom in AMC order ('rx', 'ry', 'rz'; 'tx'.. and 'l' are refused)."""


@dataclass(frozen=True)
class AsfSkeleton:
    """A parsed ASF file."""

    path: Path
    metres_per_unit: float
    angle_scale: float
    """Radians per file angle unit."""
    root_order: tuple[str, ...]
    """The root's AMC channels, e.g. ('tx', 'ty', 'tz', 'rx', 'ry', 'rz')."""
    root_axis: np.ndarray
    """(3, 3) rotation C of the root's frame."""
    root_position: np.ndarray
    """(3,) metres."""
    bones: dict[str, Bone]
    children: dict[str, list[str]] = field(default_factory=dict)
    """Children of ``root`` and of every bone, in file order."""

    def order(self) -> list[str]:
        """Bone names, parents before children (depth first from the root, in file order)."""
        out, seen, stack = [], set(), list(reversed(self.children.get("root", [])))
        while stack:
            name = stack.pop()
            out.append(name)
            if name not in seen:  # a bone listed twice (or a cycle) is expanded once; read_asf refuses it
                seen.add(name)
                stack.extend(reversed(self.children.get(name, [])))
        return out


def _read_lines(path: Path, what: str) -> list[str]:
    if not path.is_file():
        raise PGCDataError(f"{path}: {what} file not found")
    limits.check_file_size(path, MAX_CLIP_BYTES, what)
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:  # older exporters write Latin-1 comments
        text = data.decode("latin-1")
    if "\x00" in text:
        raise PGCDataError(f"{path}: binary data (NUL bytes) where an {what} text file was expected")
    return [line.split("#", 1)[0].strip() for line in text.splitlines()]


def _numbers(path: Path, where: str, tokens: list[str], count: int | None = None) -> np.ndarray:
    try:
        values = np.array([float(t) for t in tokens], dtype=np.float64)
    except ValueError:
        raise PGCDataError(f"{path}: {where}: expected numbers, got '{' '.join(tokens)}'; the file is "
                           "garbled") from None
    if count is not None and len(values) != count:
        raise PGCDataError(f"{path}: {where}: expected {count} numbers, got {len(values)} ('{' '.join(tokens)}')")
    return values


def _axis_matrix(path: Path, where: str, angles: np.ndarray, order: str, angle_scale: float) -> np.ndarray:
    if sorted(order.upper()) != ["X", "Y", "Z"]:
        raise PGCDataError(f"{path}: {where}: unsupported rotation order '{order}'; use a permutation of XYZ")
    # first listed applied first: the matrix product runs in the reverse order
    return euler_to_matrix(angles[::-1] * angle_scale, order.upper()[::-1])


def read_asf(path: str | Path) -> AsfSkeleton:
    """Parse an Acclaim ASF skeleton; errors name the file, the field and the fix."""
    path = Path(path)
    lines = _read_lines(path, "ASF skeleton")
    section, units, root, bones, children = None, {}, {}, [], {}
    bone: dict | None = None
    for number, line in enumerate(lines, 1):
        if not line:
            continue
        where = f"line {number}"
        if line.startswith(":"):
            head, *rest = line.split(None, 1)
            section = head[1:].lower()
            if section in ("version", "name") or not rest:
                continue
            line = rest[0]  # ':units' etc. may carry their first entry on the same line
        tokens = line.split()
        key = tokens[0].lower()
        if section == "units":
            units[key] = tokens[1:]
        elif section == "root":
            root[key] = tokens[1:]
        elif section == "bonedata":
            if key == "begin":
                bone = {"line": number}
            elif key == "end":
                if bone is None:
                    raise PGCDataError(f"{path}: {where}: 'end' without 'begin' in :bonedata; the file is garbled")
                bones.append(bone)
                bone = None
            elif bone is None:
                raise PGCDataError(f"{path}: {where}: '{key}' outside a begin/end block in :bonedata")
            elif key == "limits" or (key.startswith("(") and "limits" in bone):
                bone.setdefault("limits", []).extend(re.findall(r"\(([^)]*)\)", line))
            else:
                bone[key] = tokens[1:]
        elif section == "hierarchy":
            if key in ("begin", "end"):
                continue
            children.setdefault(tokens[0], []).extend(tokens[1:])
    if bone is not None:
        raise PGCDataError(f"{path}: bone block from line {bone['line']} has no 'end': the file is truncated")
    if not bones or not children:
        raise PGCDataError(f"{path}: no :bonedata or no :hierarchy section: not an ASF skeleton, or truncated")
    metres, angle_scale = _units(path, units)
    order = tuple(t.lower() for t in root.get("order", []))
    if sorted(order) != sorted(set(order)) or any(t not in (*_TRANSLATION_DOFS, *_ROTATION_DOFS) for t in order):
        raise PGCDataError(f"{path}: :root order '{' '.join(order)}': channels must be distinct TX TY TZ RX RY RZ")
    root_axis = _axis_matrix(path, ":root axis", _numbers(path, ":root orientation",
                                                          root.get("orientation", ["0", "0", "0"]), 3),
                             (root.get("axis") or ["XYZ"])[0], angle_scale)
    position = _numbers(path, ":root position", root.get("position", ["0", "0", "0"]), 3) * metres
    parsed: dict[str, Bone] = {}
    for b in bones:
        where = f"bone block at line {b['line']}"
        if "name" not in b or not b["name"]:
            raise PGCDataError(f"{path}: {where}: no 'name'")
        name = b["name"][0]
        where = f"bone '{name}'"
        for key in ("direction", "length", "axis"):
            if key not in b:
                raise PGCDataError(f"{path}: {where}: missing '{key}'")
        direction = _numbers(path, f"{where} direction", b["direction"], 3)
        norm = np.linalg.norm(direction)
        length = float(_numbers(path, f"{where} length", b["length"], 1)[0])
        if not (np.isfinite(length) and length >= 0) or not np.isfinite(norm) or (norm < 1e-9 < length):
            raise PGCDataError(f"{path}: {where}: direction and length must be finite, length >= 0")
        if len(b["axis"]) != 4:
            raise PGCDataError(f"{path}: {where} axis: expected three angles and an order (e.g. '0 0 20 XYZ')")
        axis = _axis_matrix(path, f"{where} axis", _numbers(path, f"{where} axis", b["axis"][:3], 3), b["axis"][3],
                            angle_scale)
        dof = tuple(t.lower() for t in b.get("dof", []))
        for d in dof:
            if d not in _ROTATION_DOFS:
                raise PGCDataError(f"{path}: {where} dof '{d}': only rotations (rx, ry, rz) are supported on bones "
                                   "(translations and 'l' length changes are not)")
        if len(set(dof)) != len(dof):
            raise PGCDataError(f"{path}: {where} dof '{' '.join(dof)}' repeats an axis")
        if "limits" in b and len(b["limits"]) != len(dof):
            raise PGCDataError(f"{path}: {where}: {len(b['limits'])} limits for {len(dof)} dof; give one "
                               "(min max) pair per degree of freedom")
        if name in parsed or name == "root":
            raise PGCDataError(f"{path}: {where}: the name is used twice")
        parsed[name] = Bone(name, direction / max(norm, 1e-12), length * metres, axis, dof)
    asf = AsfSkeleton(path, metres, angle_scale, order, root_axis, position, parsed, children)
    listed = asf.order()
    unknown = sorted({c for p, cs in children.items() for c in [p, *cs]} - set(parsed) - {"root"})
    if unknown:
        raise PGCDataError(f"{path}: :hierarchy names bones the :bonedata lacks: {', '.join(unknown)}")
    if len(listed) != len(set(listed)) or set(listed) != set(parsed):
        missing = sorted(set(parsed) - set(listed))
        problem = f"unreached: {', '.join(missing)}" if missing else "a bone has two parents or a cycle"
        raise PGCDataError(f"{path}: :hierarchy must reach every bone once from 'root' ({problem})")
    _check_height(path, asf_skeleton(asf).rest_positions(), "the :units length field",
                  f"CMU files say 'length 0.45' (1 unit = 1/0.45 inch); this file's is {units['length'][0]}")
    return asf


def _units(path: Path, units: dict[str, list[str]]) -> tuple[float, float]:
    """Metres per length unit and radians per angle unit of an ASF's :units section."""
    if "length" not in units or "angle" not in units:
        raise PGCDataError(f"{path}: :units must give 'length' and 'angle' (CMU: 'length 0.45', 'angle deg')")
    length = _numbers(path, ":units length", units["length"][:1], 1)[0]
    if not (np.isfinite(length) and length > 0):
        raise PGCDataError(f"{path}: :units length {length}: expected a positive number (CMU: 0.45)")
    if "mass" in units:
        mass = _numbers(path, ":units mass", units["mass"][:1], 1)[0]
        if not (np.isfinite(mass) and mass > 0):
            raise PGCDataError(f"{path}: :units mass {mass}: expected a positive number (CMU: 1.0)")
    angle = units["angle"][0].lower() if units["angle"] else ""
    if angle not in ("deg", "rad"):
        raise PGCDataError(f"{path}: :units angle '{angle}': expected 'deg' or 'rad'")
    return INCH_M / length, (np.pi / 180.0 if angle == "deg" else 1.0)


def _check_height(path: Path, rest: np.ndarray, field_name: str, hint: str) -> None:
    extent = float(np.max(rest.max(axis=0) - rest.min(axis=0)))
    lo, hi = HEIGHT_RANGE_M
    if not lo <= extent <= hi:
        raise PGCDataError(f"{path}: {field_name}: the rest skeleton spans {extent:.3g} m, not a person's "
                           f"{lo}-{hi} m: the file is in unexpected units ({hint})")


def asf_skeleton(asf: AsfSkeleton) -> Skeleton:
    """The clip skeleton of an ASF: the root, then one joint per bone at the bone's start (its rotation turns
    the bone), then one end joint ``<bone>_end`` at the end of every bone without children."""
    names, parents, offsets = ["root"], [-1], [asf.root_position]
    for name in asf.order():  # depth first: every parent comes before its children
        parent = next(p for p, cs in asf.children.items() if name in cs)
        names.append(name)
        parents.append(names.index(parent))
        offsets.append(np.zeros(3) if parent == "root" else asf.bones[parent].length * asf.bones[parent].direction)
        if not asf.children.get(name):
            names.append(f"{name}_end")
            parents.append(len(names) - 2)
            offsets.append(asf.bones[name].length * asf.bones[name].direction)
    return Skeleton(tuple(names), np.array(parents, np.int64), np.array(offsets))


@dataclass(frozen=True)
class AmcFrames:
    """Raw AMC values: per bone (and 'root') an array (T, dof) in file units."""

    path: Path
    values: dict[str, np.ndarray]
    angle_scale: float
    """Radians per angle unit."""

    @property
    def num_frames(self) -> int:
        return len(next(iter(self.values.values())))


def read_amc(path: str | Path, asf: AsfSkeleton) -> AmcFrames:
    """Parse an AMC motion against its ASF skeleton; each frame must list every bone with dofs, with as many
    values as the bone has dofs. Errors name the file, the line, the bone and the fix."""
    path = Path(path)
    lines = _read_lines(path, "AMC motion")
    expected = {"root": len(asf.root_order), **{n: len(b.dof) for n, b in asf.bones.items() if b.dof}}
    angle_scale = asf.angle_scale
    frames: list[dict[str, np.ndarray]] = []
    current: dict[str, np.ndarray] | None = None
    start = 0

    def close(frame_line: int) -> None:
        missing = [n for n in expected if n not in current]
        if missing:
            raise PGCDataError(f"{path}: frame {len(frames) + 1} (line {frame_line}) lists no values for "
                               f"{', '.join(missing)}: the file is truncated or does not belong to {asf.path.name}")
        frames.append(current)

    for number, line in enumerate(lines, 1):
        if not line:
            continue
        if line.startswith(":"):
            if frames or current is not None:
                raise PGCDataError(f"{path}: line {number}: header '{line}' after the first frame; the file is garbled")
            if line.upper() == ":RADIANS":
                angle_scale = 1.0
            elif line.upper() == ":DEGREES":
                angle_scale = np.pi / 180.0
            continue
        tokens = line.split()
        if len(tokens) == 1 and tokens[0].isdigit():
            if current is not None:
                close(start)
            if int(tokens[0]) != len(frames) + 1:
                raise PGCDataError(f"{path}: line {number}: frame number {tokens[0]}, expected {len(frames) + 1}; "
                                   "frames must be numbered 1, 2, 3, ... without gaps")
            limits.check_count(path, "frames", len(frames) + 1, limits.MAX_MOTION_FRAMES, "frames")
            current, start = {}, number
            continue
        if current is None:
            raise PGCDataError(f"{path}: line {number}: '{line[:40]}' before the first frame number; "
                               "not an AMC motion, or garbled")
        name = tokens[0]
        if name not in expected:
            known = "it has no degrees of freedom" if name in asf.bones else "the skeleton has no such bone"
            raise PGCDataError(f"{path}: line {number}: bone '{name}' does not match the skeleton {asf.path.name} "
                               f"({known}); use the ASF this clip was captured with (--skeleton FILE)")
        try:
            values = [float(t) for t in tokens[1:]]
        except ValueError:
            raise PGCDataError(f"{path}: line {number} ({name}): expected numbers, got '{' '.join(tokens[1:])}'; "
                               "the file is garbled") from None
        if len(values) != expected[name]:
            raise PGCDataError(f"{path}: line {number}: bone '{name}' has {len(values)} values but its skeleton "
                               f"{asf.path.name} gives it {expected[name]} degrees of freedom; the skeleton does "
                               "not match the clip (use its own ASF: --skeleton FILE)")
        if not all(map(math.isfinite, values)):
            raise PGCDataError(f"{path}: line {number}: frame {len(frames) + 1}, bone '{name}': NaN or infinite "
                               "angles; repair or cut those frames in the capture software")
        current[name] = values
    if current is not None:
        close(start)
    if not frames:
        raise PGCDataError(f"{path}: the clip has zero frames (no frame numbers followed by bone lines)")
    return AmcFrames(path, {n: np.array([f[n] for f in frames], np.float64).reshape(len(frames), expected[n])
                            for n in expected}, angle_scale)


def _dof_rotation(bone_dof: tuple[str, ...], values: np.ndarray, angle_scale: float) -> np.ndarray:
    """(T, 3, 3) rotation M of a bone's dof values (T, len(dof)), the first listed dof applied first."""
    order = "".join(_ROTATION_DOFS[d] for d in bone_dof)
    return euler_to_matrix(values[:, ::-1] * angle_scale, order[::-1])


def _root_motion(asf: AsfSkeleton, amc: AmcFrames) -> tuple[np.ndarray, np.ndarray]:
    """Root translation (T, 3) metres from the rest position, and local rotation (T, 3, 3)."""
    raw, order = amc.values["root"], asf.root_order
    T = len(raw)
    translation = np.zeros((T, 3))
    for k, axis in enumerate("xyz"):
        if f"t{axis}" in order:
            translation[:, k] = raw[:, order.index(f"t{axis}")] * asf.metres_per_unit
    translation -= asf.root_position  # the AMC gives the root's absolute position
    rot = [d for d in order if d in _ROTATION_DOFS]
    m = _dof_rotation(tuple(rot), raw[:, [order.index(d) for d in rot]], amc.angle_scale)
    return translation, asf.root_axis @ m @ asf.root_axis.T


def amc_clip(asf: AsfSkeleton, amc: AmcFrames, fps: float = CMU_FPS) -> Clip:
    """The :class:`Clip` of an AMC motion on its ASF skeleton (local rotation of a bone: ``C M C^-1``)."""
    skeleton = asf_skeleton(asf)
    T = amc.num_frames
    rotations = np.broadcast_to(np.eye(3), (T, len(skeleton.names), 3, 3)).copy()
    translation, rotations[:, 0] = _root_motion(asf, amc)
    for name, bone in asf.bones.items():
        if bone.dof:
            m = _dof_rotation(bone.dof, amc.values[name], amc.angle_scale)
            rotations[:, skeleton.index(name)] = bone.axis @ m @ bone.axis.T
    return Clip(skeleton, translation, rotations, fps, str(amc.path))


def bone_end_positions(asf: AsfSkeleton, amc: AmcFrames) -> dict[str, np.ndarray]:
    """Acclaim forward kinematics, written directly from the format: the root's position and the end of every
    bone, (T, 3) metres each, keyed by bone name (the reference the clip's joints are tested against)."""
    translation, root_rot = _root_motion(asf, amc)
    ends = {"root": asf.root_position + translation}
    rot = {"root": root_rot}
    for name in asf.order():
        parent = next(p for p, cs in asf.children.items() if name in cs)
        bone = asf.bones[name]
        m = _dof_rotation(bone.dof, amc.values[name], amc.angle_scale) if bone.dof else np.eye(3)
        rot[name] = rot[parent] @ bone.axis @ m @ bone.axis.T
        ends[name] = ends[parent] + bone.length * rot[name] @ bone.direction
    return ends


def subject_skeleton(amc_path: Path) -> Path:
    """The ASF beside an AMC named by its subject prefix (CMU: ``02_01.amc`` -> ``02.asf``)."""
    subject = amc_path.stem.split("_", 1)[0]
    candidate = amc_path.with_name(f"{subject}.asf")
    if not candidate.is_file():
        upper = amc_path.with_name(f"{subject}.ASF")
        if upper.is_file():
            return upper
        raise PGCDataError(f"{amc_path}: no skeleton {candidate.name} beside the clip; an AMC needs its ASF: put it "
                           "there or pass --skeleton FILE")
    return candidate


def read_amc_clip(path: str | Path, skeleton: str | Path | None = None, fps: float | None = None) -> Clip:
    """The clip of an AMC file on its ASF (``skeleton``, default: the subject's ASF beside it) at ``fps``
    (default :data:`CMU_FPS`)."""
    path = Path(path)
    asf = read_asf(Path(skeleton) if skeleton else subject_skeleton(path))
    return amc_clip(asf, read_amc(path, asf), CMU_FPS if fps is None else fps)
