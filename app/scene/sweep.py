"""Sweep cases: a scene with a ``sweep:`` section (schema: :class:`app.scene.schema.Sweep`) expanded
into named, validated scenes (app/study/sweep.py runs them).

Each case is the base scene with each swept key (a dotted path such as ``system.length``) set to
one of its values, every combination (``mode: product``) or the i-th values together
(``mode: zip``). Each case is validated as a normal scene before anything runs and gets a stable
name made from its values, e.g. ``mu=1.1_system.length=80``.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import pathlib
import re
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from app.scene.schema import Scene, SceneError, format_error, scene_context


@dataclass(frozen=True)
class Case:
    """One case of a sweep: its position in the sweep, its folder name, the value of each swept key,
    its validated scene and the hash of that scene (:func:`scene_hash`, which tells a restart
    whether stored results are this case's)."""

    index: int
    name: str
    values: dict              # swept key -> value
    scene: Scene
    scene_hash: str


def format_value(v: Any) -> str:
    """The text of a swept value in case names and tables (floats to 12 significant digits)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.12g}"
    if v is None:
        return "null"
    if isinstance(v, (list, tuple)):
        return ",".join(format_value(x) for x in v)
    return str(v)


def case_name(values: dict) -> str:
    """Stable folder name of a case: ``key=value`` joined by ``_``, e.g. ``mu=1.1_system.length=80``."""
    name = "_".join(f"{k}={format_value(v)}" for k, v in values.items())
    name = re.sub(r"[^A-Za-z0-9_.=,+\-]", "-", name)
    if len(name) > 150:      # keep folder names well below the 255-byte limit
        name = name[:130] + "~" + hashlib.sha1(name.encode()).hexdigest()[:12]
    return name


def scene_hash(scene: Scene) -> str:
    """Hash of everything that determines a case's results (its whole validated scene but the name)."""
    text = json.dumps(scene.model_dump(mode="json", exclude={"name"}), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _set(data: dict, key: str, value: Any) -> None:
    *parents, last = key.split(".")
    for p in parents:
        sub = data.get(p)
        if not isinstance(sub, dict):
            sub = data[p] = {}
        data = sub
    data[last] = list(value) if isinstance(value, tuple) else value


def expand(scene: Scene, source: str = "scene", base_dir: str | pathlib.Path | None = None) -> list[Case]:
    """The cases of a sweep scene, each validated as a normal scene.

    ``base_dir`` is the scene file's folder: a swept file value (``system.file``, ``system.K``)
    that is a relative path is resolved against it, like the same key written in the scene (the
    base scene's own paths are already absolute in its dump).

    Raises :class:`SceneError` (one line, naming the case) when a value makes a case invalid.
    """
    sw = scene.sweep
    if sw is None:
        raise ValueError("not a sweep scene")
    keys = list(sw.parameters)
    columns = [sw.parameters[k] for k in keys]
    combos = zip(*columns) if sw.mode == "zip" else itertools.product(*columns)
    # only what the user wrote (defaults are filled in again when each case is validated)
    base = scene.model_dump(exclude_unset=True, exclude={"sweep"})
    cases, names = [], {}
    for i, combo in enumerate(combos):
        values = dict(zip(keys, combo))
        name = case_name(values)
        if name in names:
            raise SceneError(f"{source}: sweep: cases {names[name] + 1} and {i + 1} get the same name "
                             f"'{name}': list each value once (80 and 80.0 are the same value)")
        names[name] = i
        data = json.loads(json.dumps(base))     # deep copy, tuples as lists
        for k, v in values.items():
            _set(data, k, v)
        try:
            case_scene = Scene.model_validate(data, context=scene_context(data, base_dir))
        except ValidationError as err:
            raise SceneError(f"{source}: sweep case '{name}': {format_error(err)}") from None
        except RecursionError:
            raise SceneError(f"{source}: sweep case '{name}': the scene is nested too deeply") from None
        cases.append(Case(i, name, values, case_scene, scene_hash(case_scene)))
    return cases
