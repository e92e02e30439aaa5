"""The sweep file: scenes x configurations x steps, and the table to build (format in docs/sweeps.md).

Everything is checked before any work: an unknown table or key, a bad value, a configuration the run
configuration rejects, a step or motion that does not exist raises :class:`PGCConfigError` naming the file
and the key.
"""

from __future__ import annotations

import itertools
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from pgc import config as config_mod
from pgc.errors import PGCConfigError, PGCDataError
from pgc.io.limits import read_toml

STEPS = ("reconstruct", "animate", "render", "eval")
"""The steps in pipeline order; a sweep runs a prefix of them."""
SWEEP_KEYS = {"name", "base", "config", "steps", "motions", "lights", "modes", "holdout_every"}
SYNTH_KEYS = {"preset", "garment", "fabric", "seed", "framing", "detail", "fit", "looseness", "views", "capture_light"}
SCENE_KEYS = SYNTH_KEYS | {"capture"}
NUMERIC_KEYS = ("seed", "looseness", "views")
"""Synthetic-scene keys whose values name a varied scene with the key in front (``-seed3``, ``-looseness0.03``)."""
VIEWS = (2, 1024)
"""The range of a synthetic scene's camera count (``views``: the preset's unless given)."""
LOOSENESS = (0.01, 0.15)
"""The garment generator's range of clearance from the body, metres (``pgc synth --looseness``)."""
TABLE_KEYS = {"rows", "columns", "metrics", "where", "reference"}
TOP_KEYS = {"sweep", "scenes", "configurations", "table"}
SCENE_RECORD_FIELDS = ("preset", "garment", "fabric", "seed", "framing", "detail", "fit", "looseness", "views",
                       "capture_light")
"""A synthetic scene's keys as every record carries them (None where the scene left one to its preset)."""
RECORD_FIELDS = ("scene", "configuration", "motion", "light", "mode", "variant", *SCENE_RECORD_FIELDS)
"""Record fields a table may group or filter by."""
SEED_FIELDS = ("scene", "seed")
"""The fields that name a seed: a synthetic scene's name carries its seed (``-seed1``); records pair across
neither, and the other fields name a scene without its seed."""


@dataclass
class Scene:
    name: str
    synth: dict[str, Any] | None
    """preset, garment, fabric, seed, framing of a synthetic scene, and detail, fit, looseness, views, capture_light
    where the sweep file gives them (None for a capture folder)."""
    capture: Path | None = None


@dataclass
class Configuration:
    name: str
    data: dict[str, Any]
    """The run configuration's TOML tables: the base preset, the sweep's config file, then the overrides."""
    source: str
    cfg: Any = None
    """The validated :class:`pgc.config.RunConfig`."""


@dataclass
class Table:
    rows: list[str] = field(default_factory=lambda: ["configuration"])
    columns: list[str] = field(default_factory=list)
    metrics: list[str] = field(default_factory=list)
    """Metrics shown (default: every metric of the records)."""
    where: dict[str, list[Any]] = field(default_factory=dict)
    """Record field -> allowed values."""
    reference: dict[str, Any] = field(default_factory=dict)
    """One record field -> the value every other value of it is compared with, record by record
    (:mod:`pgc.sweep.paired`); empty: no paired table."""


def selected(records: list[dict[str, Any]], table: Table) -> list[dict[str, Any]]:
    """The records that ``table.where`` admits."""
    return [r for r in records if all(r.get(k) in v for k, v in table.where.items())]


@dataclass
class Sweep:
    path: Path
    name: str
    steps: list[str]
    motions: list[str]
    scenes: list[Scene]
    configurations: list[Configuration]
    table: Table
    lights: list[str] = field(default_factory=lambda: ["capture"])
    """The lights runs are rendered and evaluated under (:data:`pgc.pipeline.relight.EVAL_LIGHTS`)."""
    modes: list[str] = field(default_factory=lambda: ["appearance"])
    """The evaluation modes recorded (:data:`pgc.stages.eval.MODES`)."""
    holdout_every: int = 0
    """Every k-th view of each scene's capture is held out of the reconstruction, and the runs are rendered and
    evaluated from the held-out cameras only (0: every view reconstructs, runs render from all)."""


def _fail(path: Path, key: str, message: str) -> PGCConfigError:
    return PGCConfigError(f"{path}: {key}: {message}")


def _unknown(path: Path, where: str, given: dict[str, Any], allowed: set[str]) -> None:
    extra = sorted(set(given) - allowed)
    if extra:
        raise _fail(path, f"{where}.{extra[0]}" if where else extra[0],
                    f"unknown key; allowed: {', '.join(sorted(allowed))}")


def load_sweep(path: str | Path, registry: Any = None) -> Sweep:
    """Parse and validate a sweep file (see the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise PGCConfigError(f"{path}: sweep file not found")
    try:
        data = read_toml(path)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise PGCConfigError(f"{path}: not valid TOML ({exc})") from None
    except PGCDataError as exc:  # a size or nesting limit
        raise PGCConfigError(str(exc)) from None
    _unknown(path, "", data, TOP_KEYS)
    head = _table(path, data, "sweep")
    _unknown(path, "[sweep]", head, SWEEP_KEYS)
    if "name" in head:
        _check_name(path, "[sweep].name", head["name"])
    for key in ("base", "config"):
        if key in head and not isinstance(head[key], str):
            raise _fail(path, f"[sweep].{key}", f"{head[key]!r}: give a string ("
                        + ("a demo preset name" if key == "base" else "a run configuration file") + ")")
    steps = head.get("steps", list(STEPS))
    if not isinstance(steps, list) or not steps:
        raise _fail(path, "[sweep].steps", f"give a list of steps from {', '.join(STEPS)}")
    for s in steps:
        if s not in STEPS:
            raise _fail(path, "[sweep].steps", f"unknown step '{s}'; steps: {', '.join(STEPS)}")
    if list(steps) != list(STEPS[:len(steps)]):
        raise _fail(path, "[sweep].steps", f"{steps}: each step needs the ones before it; give a prefix of "
                                           f"{list(STEPS)}")
    motions = head.get("motions", [])
    if not isinstance(motions, list) or not all(isinstance(m, str) for m in motions):
        raise _fail(path, "[sweep].motions", "give a list of motion names or files")
    if "animate" in steps and not motions:
        raise _fail(path, "[sweep].motions", "the step 'animate' needs at least one motion")
    _check_motions(path, motions, path.parent)
    scenes = _scenes(path, _table(path, data, "scenes", required=True))
    configurations = _configurations(path, head, _table(path, data, "configurations", required=True), registry)
    table = _table_spec(path, _table(path, data, "table"))
    if table.metrics and "eval" in steps:
        known = {i.name for c in configurations for i in c.cfg.roles["metric"].implementations}
        for m in table.metrics:
            if m not in known:
                raise _fail(path, "[table].metrics", f"unknown metric '{m}'; the configurations' metrics: "
                                                     f"{', '.join(sorted(known))}")
    if "eval" in steps:
        for s in scenes:
            if s.capture is not None and not (s.capture / "ground_truth").is_dir():
                raise _fail(path, f"[scenes.{s.name}].capture", f"{s.capture} has no ground_truth/ folder, so "
                                                                "'eval' has nothing to compare with; drop 'eval' "
                                                                "from [sweep].steps")
    lights = _lights(path, head)
    modes = _modes(path, head, steps)
    for name, values in (("light", lights), ("mode", modes)):
        if len(values) > 1 and "eval" in steps and name not in [*table.rows, *table.columns, *table.where]:
            table.columns.append(name)  # a cell never averages over lights or modes
    return Sweep(path, str(head.get("name", path.stem)), list(steps), list(motions), scenes, configurations, table,
                 lights, modes, _holdout_every(path, head, steps))


def _modes(path: Path, head: dict[str, Any], steps: list[str]) -> list[str]:
    """``[sweep].modes`` (default ``["appearance"]``), checked: modes of :data:`pgc.stages.eval.MODES`, once each,
    and only with the step 'eval'."""
    from pgc.stages.eval import MODES

    if "modes" not in head:
        return ["appearance"]
    modes = head["modes"]
    if not isinstance(modes, list) or not modes or not all(isinstance(m, str) for m in modes):
        raise _fail(path, "[sweep].modes", f"give a non-empty list of evaluation modes from {', '.join(MODES)}")
    for m in modes:
        if m not in MODES:
            raise _fail(path, "[sweep].modes", f"unknown mode '{m}'; modes: {', '.join(MODES)}")
    if len(set(modes)) != len(modes):
        raise _fail(path, "[sweep].modes", f"a mode is named twice in {modes}")
    if "eval" not in steps:
        raise _fail(path, "[sweep].modes", "evaluation modes need the step 'eval' in [sweep].steps")
    return list(modes)


def _holdout_every(path: Path, head: dict[str, Any], steps: list[str]) -> int:
    """``[sweep].holdout_every`` (default 0: off), checked: an integer >= 2, with the step 'render'."""
    k = head.get("holdout_every", 0)
    if not isinstance(k, int) or isinstance(k, bool) or (k != 0 and k < 2):
        raise _fail(path, "[sweep].holdout_every", f"{k!r}: give an integer >= 2 (every k-th view is held out of "
                                                   "the reconstruction) or 0 (none)")
    if k and "render" not in steps:
        raise _fail(path, "[sweep].holdout_every", "held-out views are rendered and evaluated: the sweep needs the "
                                                   "step 'render' in [sweep].steps")
    return k


def _lights(path: Path, head: dict[str, Any]) -> list[str]:
    """``[sweep].lights`` (default every light of :data:`pgc.pipeline.relight.EVAL_LIGHTS`), checked."""
    from pgc.pipeline.relight import EVAL_LIGHTS, check_light_names

    lights = head.get("lights", list(EVAL_LIGHTS))
    if not isinstance(lights, list) or not all(isinstance(x, str) for x in lights):
        raise _fail(path, "[sweep].lights", f"give a list of light names from {', '.join(EVAL_LIGHTS)}")
    return check_light_names(lights, f"{path}: [sweep].lights")


def _table(path: Path, data: dict[str, Any], key: str, required: bool = False) -> dict[str, Any]:
    value = data.get(key)
    if value is None:
        if required:
            raise _fail(path, f"[{key}]", "missing; the sweep needs at least one entry there")
        return {}
    if not isinstance(value, dict) or (required and not value):
        raise _fail(path, f"[{key}]", "must be a table" + (" with at least one entry" if required else ""))
    return value


NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
"""Names that become parts of folder names (the sweep's, its scenes')."""


def _check_name(path: Path, key: str, name: Any) -> None:
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise _fail(path, key, f"{name!r}: a name here becomes part of a folder name; use letters, digits, '_', "
                               "'.' and '-' (starting with a letter or digit)")


def _check_motions(path: Path, motions: list[str], root: Path) -> None:
    from pgc.errors import PGCDataError
    from pgc.io.motion import load_motion
    from pgc.motion.amass import is_pose_npz, read_pose_arrays
    from pgc.motion.drive import SHIPPED_PREFIX, is_clip, load_clip, shipped_clip
    from pgc.synth.motions import MOTIONS

    for m in motions:
        if m in MOTIONS:
            continue
        shipped = m.startswith(SHIPPED_PREFIX)
        if not shipped and not (root / m).exists():
            raise _fail(path, "[sweep].motions", f"'{m}' is neither a built-in motion ({', '.join(MOTIONS)}), a "
                                                 f"shipped clip ({SHIPPED_PREFIX}NAME) nor a file (paths are "
                                                 "relative to the sweep file)")
        try:
            if not shipped and is_pose_npz(root / m):
                read_pose_arrays(root / m)  # its skeleton comes from the configured body model, at run time
            elif shipped or is_clip(root / m):
                load_clip(shipped_clip(m) if shipped else root / m)
            else:
                load_motion(root / m)
        except PGCDataError as exc:
            raise _fail(path, "[sweep].motions", str(exc)) from None


def _scenes(path: Path, table: dict[str, Any]) -> list[Scene]:
    from pgc.synth.detail import DETAILS
    from pgc.synth.fabrics import FABRICS
    from pgc.synth.garments import FITS, GARMENTS
    from pgc.synth.generate import PRESETS
    from pgc.synth.rig import CAPTURE_LIGHTS

    choices = {"preset": tuple(PRESETS), "garment": GARMENTS, "fabric": tuple(FABRICS), "framing": ("body", "garment"),
               "detail": tuple(DETAILS), "fit": FITS, "capture_light": CAPTURE_LIGHTS}
    out = []
    for name, spec in table.items():
        where = f"[scenes.{name}]"
        _check_name(path, where, name)
        if not isinstance(spec, dict):
            raise _fail(path, where, "must be a table (preset, garment, fabric, seed, framing, detail, fit, "
                                     "looseness, views, capture_light; or capture)")
        _unknown(path, where, spec, SCENE_KEYS)
        if "capture" in spec:
            if set(spec) & SYNTH_KEYS:
                raise _fail(path, where, "give either 'capture' (a folder) or a synthetic spec, not both")
            if not isinstance(spec["capture"], str):
                raise _fail(path, f"{where}.capture", f"{spec['capture']!r}: give the capture folder's path (a "
                                                      "string, relative to the sweep file)")
            folder = (path.parent / spec["capture"]).resolve()
            if not (folder / "transforms.json").is_file():
                raise _fail(path, f"{where}.capture", f"{folder} is not a capture folder (no transforms.json)")
            out.append(Scene(name, None, folder))
            continue
        lists = {k: v if isinstance(v, list) else [v] for k, v in spec.items()}
        for key, values in lists.items():
            for v in values:
                if key == "seed" and (not isinstance(v, int) or isinstance(v, bool) or v < 0):
                    raise _fail(path, f"{where}.seed", f"{v!r}: give a non-negative integer (or a list of them)")
                if key == "looseness" and (not isinstance(v, (int, float)) or isinstance(v, bool)
                                           or not LOOSENESS[0] <= v <= LOOSENESS[1]):
                    raise _fail(path, f"{where}.looseness", f"{v!r}: give the garment's clearance from the body in "
                                                            f"metres, in [{LOOSENESS[0]}, {LOOSENESS[1]}] (or a "
                                                            "list of them)")
                if key == "views" and (not isinstance(v, int) or isinstance(v, bool)
                                       or not VIEWS[0] <= v <= VIEWS[1]):
                    raise _fail(path, f"{where}.views", f"{v!r}: give the number of capture cameras, an integer in "
                                                        f"[{VIEWS[0]}, {VIEWS[1]}] (or a list of them)")
                if key in choices and v not in choices[key]:
                    raise _fail(path, f"{where}.{key}", f"unknown {key} {v!r}; choose from {', '.join(choices[key])}")
        varying = [k for k, v in lists.items() if len(v) > 1]
        for combo in itertools.product(*lists.values()):
            values = dict(zip(lists, combo))
            # detail, fit, looseness, views and capture_light enter the spec only when given, so the scene keys of
            # sweeps without them (and their cached captures) stay as they were
            synth = {"preset": "tiny", "garment": None, "fabric": None, "seed": 0, "framing": None} | values
            suffix = "".join(f"-{k}{values[k]}" if k in NUMERIC_KEYS else f"-{values[k]}" for k in varying)
            out.append(Scene(name + suffix, synth))
    return out


def base_data(base: str | None, config_file: Path | None) -> dict[str, Any]:
    """The configuration every configuration starts from: the demo preset's settings
    (``pgc/presets/demo_<base>.toml``) under the sweep's config file."""
    data: dict[str, Any] = {}
    if base is not None:
        preset_file = resources.files("pgc") / "presets" / f"demo_{base}.toml"
        data = config_mod.load_toml(str(preset_file))
    if config_file is not None:
        data = config_mod.deep_merge(data, config_mod.load_toml(config_file))
    return data


def _configurations(path: Path, head: dict[str, Any], table: dict[str, Any], registry: Any) -> list[Configuration]:
    base = head.get("base")
    presets = sorted(p.name[len("demo_"):-len(".toml")] for p in (resources.files("pgc") / "presets").iterdir()
                     if p.name.startswith("demo_"))
    if base is not None and base not in presets:
        raise _fail(path, "[sweep].base", f"unknown preset '{base}'; presets: {', '.join(presets)}")
    config_file = (path.parent / head["config"]) if "config" in head else None
    if config_file is not None and not config_file.is_file():
        raise _fail(path, "[sweep].config", f"{config_file} not found (paths are relative to the sweep file)")
    start = base_data(base, config_file)
    if registry is None:
        from pgc.registry import default_registry

        registry = default_registry()
    out = []
    for name, overrides in table.items():
        if not isinstance(overrides, dict):
            raise _fail(path, f"[configurations.{name}]", "must be a table of run-configuration overrides "
                                                          "(an empty table keeps the base)")
        source = f"{path} [configurations.{name}]"
        conf = Configuration(name, config_mod.deep_merge(start, overrides), source)
        conf.cfg = config_mod.resolve(conf.data, registry, source=source)
        conf.cfg.check_implementations()
        out.append(conf)
    return out


def _table_spec(path: Path, table: dict[str, Any]) -> Table:
    _unknown(path, "[table]", table, TABLE_KEYS)
    spec = Table()
    for key in ("rows", "columns", "metrics"):
        if key in table:
            value = table[key]
            value = [value] if isinstance(value, str) else value
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise _fail(path, f"[table].{key}", "give a field name or a list of them")
            if key != "metrics":
                for v in value:
                    if v not in RECORD_FIELDS:
                        raise _fail(path, f"[table].{key}", f"unknown field '{v}'; fields: {', '.join(RECORD_FIELDS)}")
            setattr(spec, key, value)
    where = table.get("where", {})
    if not isinstance(where, dict):
        raise _fail(path, "[table].where", "must be a table of field = value (or list of values)")
    for k, v in where.items():
        if k not in RECORD_FIELDS:
            raise _fail(path, f"[table].where.{k}", f"unknown field; fields: {', '.join(RECORD_FIELDS)}")
        spec.where[k] = v if isinstance(v, list) else [v]
    reference = table.get("reference", {})
    if not isinstance(reference, dict) or len(reference) > 1:
        raise _fail(path, "[table].reference", 'give one field and its reference value, e.g. '
                                               'reference = { variant = "hybrid" }')
    for k, v in reference.items():
        if k not in RECORD_FIELDS or k in SEED_FIELDS:
            raise _fail(path, f"[table].reference.{k}", "give a field the records pair on: "
                        + ", ".join(f for f in RECORD_FIELDS if f not in SEED_FIELDS))
        if not isinstance(v, (str, int, float)) or isinstance(v, bool):
            raise _fail(path, f"[table].reference.{k}", "give one value (a name or a number)")
    spec.reference = dict(reference)
    return spec
