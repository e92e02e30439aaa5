"""BVH motion files: reader (any rotation channel order) and writer.

``HIERARCHY``: ``ROOT``/``JOINT`` blocks with ``OFFSET`` (from the parent, file units), ``CHANNELS`` (the root:
``Xposition Yposition Zposition`` and rotations; other joints: rotations only) and ``End Site`` blocks (read as
joints ``<parent>_end`` without channels). ``MOTION``: ``Frames:``, ``Frame Time:`` (seconds) and one line of
channel values per frame, angles in degrees. Rotation channels compose in the listed order: ``Zrotation
Xrotation Yrotation`` is ``Rz @ Rx @ Ry``. BVH carries no length unit: ``unit_m`` (metres per file unit,
default centimetres) says it, and a skeleton that does not come out the size of a person is refused.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from pgc.errors import PGCDataError
from pgc.io import limits
from pgc.io.atomic import write_text
from pgc.motion.asf import HEIGHT_RANGE_M, MAX_CLIP_BYTES
from pgc.motion.clip import Clip, Skeleton
from pgc.motion.rotations import euler_to_matrix

DEFAULT_UNIT_M = 0.01
"""Metres per BVH length unit when the caller gives none (centimetres, the common exporters' unit)."""
_POSITION = ("Xposition", "Yposition", "Zposition")
_ROTATION = {"Xrotation": "X", "Yrotation": "Y", "Zrotation": "Z"}
MAX_DEPTH = 256
"""Deepest joint nesting read (a body's chains nest about 10 levels)."""
WRITE_ORDER = "ZYX"
"""Rotation channel order of written files (``Zrotation Yrotation Xrotation``, as CMU's BVH conversions; the
angles come from :func:`matrix_to_euler_zyx`)."""


class _Tokens:
    def __init__(self, path: Path, text: str):
        self.path = path
        self.items: list[tuple[str, int]] = [(tok, n) for n, line in enumerate(text.splitlines(), 1)
                                             for tok in line.split()]
        self.i = 0

    def next(self, what: str) -> str:
        if self.i >= len(self.items):
            raise PGCDataError(f"{self.path}: the file ends where {what} was expected: it is truncated")
        tok = self.items[self.i][0]
        self.i += 1
        return tok

    def expect(self, word: str) -> None:
        tok = self.next(f"'{word}'")
        if tok != word:
            raise PGCDataError(f"{self.path}: line {self.items[self.i - 1][1]}: expected '{word}', found '{tok}'; "
                               "the file is garbled")

    def number(self, what: str) -> float:
        tok = self.next(what)
        try:
            return float(tok)
        except ValueError:
            raise PGCDataError(f"{self.path}: line {self.items[self.i - 1][1]}: {what}: expected a number, found "
                               f"'{tok}'") from None

    @property
    def line(self) -> int:
        return self.items[min(self.i, len(self.items) - 1)][1] if self.items else 0


def read_bvh(path: str | Path, unit_m: float = DEFAULT_UNIT_M) -> Clip:
    """Parse a BVH file into a :class:`Clip` (lengths x ``unit_m`` metres); errors name file, line and fix."""
    path = Path(path)
    if not path.is_file():
        raise PGCDataError(f"{path}: BVH file not found")
    if not (math.isfinite(unit_m) and unit_m > 0):
        raise PGCDataError(f"BVH unit {unit_m}: metres per file unit must be a positive number (centimetres: 0.01)")
    limits.check_file_size(path, MAX_CLIP_BYTES, "BVH file")
    text = path.read_bytes().decode("latin-1")
    head, sep, motion = text.partition("MOTION")
    if not sep:
        raise PGCDataError(f"{path}: no MOTION section: not a BVH file, or truncated")
    tokens = _Tokens(path, head)
    tokens.expect("HIERARCHY")
    names: list[str] = []
    parents: list[int] = []
    offsets: list[np.ndarray] = []
    channels: list[list[str]] = []

    def block(parent: int, kind: str, depth: int = 0) -> None:
        if depth > MAX_DEPTH:
            raise PGCDataError(f"{path}: line {tokens.line}: joints nest deeper than {MAX_DEPTH} levels; the file "
                               "is garbled or not a body's skeleton")
        if kind == "End":
            tokens.expect("Site")
            name = f"{names[parent]}_end"
        else:
            name = tokens.next("a joint name")
        if name in names:
            raise PGCDataError(f"{path}: line {tokens.line}: joint name '{name}' is used twice")
        index = len(names)
        names.append(name)
        parents.append(parent)
        tokens.expect("{")
        tokens.expect("OFFSET")
        offsets.append(np.array([tokens.number(f"OFFSET of '{name}'") for _ in range(3)]))
        channels.append([])
        if kind != "End":
            tokens.expect("CHANNELS")
            count = tokens.number(f"CHANNELS count of '{name}'")
            if count != int(count) or not 0 <= count <= 6:
                raise PGCDataError(f"{path}: line {tokens.line}: CHANNELS count {count} of '{name}' must be 0..6")
            channels[index] = [tokens.next(f"a channel of '{name}'") for _ in range(int(count))]
            _check_channels(path, name, channels[index], root=parent < 0)
        limits.check_count(path, "joints", len(names), 10_000, "joints")
        while True:
            tok = tokens.next(f"'}}' closing '{name}'")
            if tok == "}":
                return
            if kind == "End" or tok not in ("JOINT", "End"):
                raise PGCDataError(f"{path}: line {tokens.line}: unexpected '{tok}' in '{name}'; the file is garbled")
            block(index, tok, depth + 1)

    tokens.expect("ROOT")
    block(-1, "ROOT")
    fps, values = _motion(path, motion, sum(len(c) for c in channels))
    skeleton = Skeleton(tuple(names), np.array(parents), np.array(offsets) * unit_m)
    _check_size(path, skeleton, unit_m)
    T, J = len(values), len(names)
    rotations = np.broadcast_to(np.eye(3), (T, J, 3, 3)).copy()
    translation = np.zeros((T, 3))
    column = 0
    for j, chans in enumerate(channels):
        cols = {c: column + k for k, c in enumerate(chans)}
        column += len(chans)
        rot = [c for c in chans if c in _ROTATION]
        if rot:
            angles = np.deg2rad(values[:, [cols[c] for c in rot]])
            rotations[:, j] = euler_to_matrix(angles, "".join(_ROTATION[c] for c in rot))
        for k, c in enumerate(_POSITION):
            if c in cols:
                translation[:, k] = values[:, cols[c]] * unit_m
    return Clip(skeleton, translation, rotations, fps, str(path))


def _check_channels(path: Path, name: str, chans: list[str], root: bool) -> None:
    for c in chans:
        if c not in _ROTATION and c not in _POSITION:
            raise PGCDataError(f"{path}: joint '{name}': unknown channel '{c}'; BVH channels are X/Y/Zposition and "
                               "X/Y/Zrotation")
        if c in _POSITION and not root:
            raise PGCDataError(f"{path}: joint '{name}': position channel '{c}' on a joint other than the root is "
                               "not supported; re-export with rotations only below the root")
    rot = [c for c in chans if c in _ROTATION]
    if len(set(rot)) != len(rot) or len(set(chans)) != len(chans):
        raise PGCDataError(f"{path}: joint '{name}': unsupported rotation order '{' '.join(rot)}' (an axis repeats); "
                           "each of X, Y, Z may appear once, in any order")


def _motion(path: Path, text: str, num_channels: int) -> tuple[float, np.ndarray]:
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    if len(lines) < 2 or not lines[0].startswith("Frames:") or not lines[1].startswith("Frame Time:"):
        raise PGCDataError(f"{path}: MOTION must start with 'Frames: N' and 'Frame Time: SECONDS'; the file is "
                           "truncated or garbled")
    try:
        frames = int(lines[0].split(":", 1)[1])
        dt = float(lines[1].split(":", 1)[1])
    except ValueError:
        raise PGCDataError(f"{path}: 'Frames:' must be an integer and 'Frame Time:' a number of seconds") from None
    if frames <= 0:
        raise PGCDataError(f"{path}: Frames: {frames}: the clip has zero frames; a motion needs at least one")
    limits.check_count(path, "Frames", frames, limits.MAX_MOTION_FRAMES, "frames")
    if not (math.isfinite(dt) and 0 < dt <= 10):
        raise PGCDataError(f"{path}: Frame Time: {dt} s must be a positive number of seconds (e.g. 0.0333333)")
    rows = lines[2:]
    if len(rows) != frames:
        raise PGCDataError(f"{path}: 'Frames: {frames}' but {len(rows)} lines of values follow; the file is "
                           "truncated or the count is wrong")
    values = np.full((frames, num_channels), np.nan)
    for t, row in enumerate(rows):
        tokens = row.split()
        if len(tokens) != num_channels:
            raise PGCDataError(f"{path}: frame {t} has {len(tokens)} values, the hierarchy has {num_channels} "
                               "channels; the file is truncated or garbled")
        try:
            values[t] = [float(v) for v in tokens]
        except ValueError:
            raise PGCDataError(f"{path}: frame {t}: a value is not a number ('{row[:60]}...')") from None
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        raise PGCDataError(f"{path}: frame {int(np.argmax(bad))} (0-based): NaN or infinite channel values in "
                           f"{int(bad.sum())} frame(s); repair or cut those frames")
    return 1.0 / dt, values


def _check_size(path: Path, skeleton: Skeleton, unit_m: float) -> None:
    rest = skeleton.rest_positions()
    extent = float(np.max(rest.max(axis=0) - rest.min(axis=0)))
    lo, hi = HEIGHT_RANGE_M
    if not lo <= extent <= hi:
        raise PGCDataError(f"{path}: OFFSET: at {unit_m} m per unit the rest skeleton spans {extent:.3g} m, not a "
                           f"person's {lo}-{hi} m; give the file's length unit (--clip-unit METRES: 0.01 for "
                           "centimetres, 0.0254 for inches, 1 for metres)")


def matrix_to_euler_zyx(m: np.ndarray) -> np.ndarray:
    """(..., 3) angles (z, y, x) radians with ``Rz(z) @ Ry(y) @ Rx(x) = m`` for rotations (..., 3, 3)."""
    m = np.asarray(m, np.float64)
    cy = np.hypot(m[..., 0, 0], m[..., 1, 0])
    y = np.arctan2(-m[..., 2, 0], cy)
    regular = cy > 1e-9
    z = np.where(regular, np.arctan2(m[..., 1, 0], m[..., 0, 0]), 0.0)
    x_regular = np.arctan2(m[..., 2, 1], m[..., 2, 2])
    # gimbal lock (y = +-90 degrees): only x - z (y > 0) or x + z (y < 0) is determined; z = 0
    x_lock = np.where(m[..., 2, 0] < 0, np.arctan2(m[..., 0, 1], m[..., 0, 2]),
                      np.arctan2(-m[..., 0, 1], -m[..., 0, 2]))
    return np.stack([z, y, np.where(regular, x_regular, x_lock)], axis=-1)


def write_bvh(path: str | Path, clip: Clip, unit_m: float = DEFAULT_UNIT_M) -> None:
    """Write ``clip`` as BVH (atomically), lengths in units of ``unit_m`` metres, rotations as
    ``Zrotation Yrotation Xrotation`` degrees with 10 significant digits. Joints named ``<parent>_end`` without
    children or rotation become ``End Site`` blocks (as :func:`read_bvh` reads them)."""
    sk = clip.skeleton
    children: dict[int, list[int]] = {j: [] for j in range(len(sk.names))}
    for j, p in enumerate(sk.parents):
        if p >= 0:
            children[int(p)].append(j)
    identity = np.all(np.abs(clip.rotations - np.eye(3)) < 1e-12, axis=(0, 2, 3))
    end_site = [not children[j] and identity[j] and sk.parents[j] >= 0
                and sk.names[j] == f"{sk.names[sk.parents[j]]}_end" for j in range(len(sk.names))]
    out: list[str] = ["HIERARCHY"]
    order: list[int] = []

    def num(x: float) -> str:
        return f"{x:.10g}"

    def joint(j: int, depth: int) -> None:
        pad = "  " * depth
        off = " ".join(num(v) for v in sk.offsets[j] / unit_m)
        if end_site[j]:
            out.extend([f"{pad}End Site", f"{pad}{{", f"{pad}  OFFSET {off}", f"{pad}}}"])
            return
        order.append(j)
        out.append(f"{pad}{'ROOT' if sk.parents[j] < 0 else 'JOINT'} {sk.names[j]}")
        out.extend([f"{pad}{{", f"{pad}  OFFSET {off}"])
        chans = " ".join(f"{axis}rotation" for axis in WRITE_ORDER)
        out.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {chans}" if sk.parents[j] < 0
                   else f"{pad}  CHANNELS 3 {chans}")
        for c in children[j]:
            joint(c, depth + 1)
        out.append(f"{pad}}}")

    joint(0, 0)
    angles = np.rad2deg(matrix_to_euler_zyx(clip.rotations[:, order]))  # (T, J', 3)
    rows = np.concatenate([clip.root_translation / unit_m, angles.reshape(clip.num_frames, -1)], axis=1)
    out += ["MOTION", f"Frames: {clip.num_frames}", f"Frame Time: {1.0 / clip.fps:.10g}"]
    out += [" ".join(num(v) for v in row) for row in rows]
    write_text(path, "\n".join(out) + "\n")
