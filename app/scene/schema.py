"""Scene files: YAML validated by pydantic into typed, frozen objects.

A scene names the system, the friction coefficient, the loading (for the FE block) and the
analyses wanted. Validation errors become one line naming the key path, the bad value and what
is allowed (:class:`SceneError`); the CLI prints that line and exits with status 2.
"""
from __future__ import annotations

import difflib
import pathlib
import re
from typing import Annotated, Any, Literal, Optional, Sequence, Union

import yaml
from pydantic import BaseModel, Field, ValidationError, field_validator, model_validator

from app.common.validation import PathError, ResourcePathError, SceneError, Strict, one_line, show_value
from app.scene.sections import (  # noqa: F401 - re-exported: app.scene.schema is where scenes are described
    STATE_WORDS,
    EigSettings,
    Limits,
    McpSettings,
    Outputs,
    Refinement,
    Screenshots,
    Settings,
    StateCounts,
    Sweep,
    Transient,
    annotation_types,
)
from app.systems import SYSTEM_TYPES
from app.systems import schemas as registered_schemas
from app.systems.block.schema import Block, Loading  # noqa: F401 - re-exported (app.scene.schema.Block)
from app.systems.particles.schema import TwoParticles  # noqa: F401 - re-exported
from app.systems.schema import NonNegFloat

Analysis = Literal["necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"]


def _check_sweep_keys(scene: "Scene") -> None:
    """Every swept key must name a key of the scene's schema (the system's, for system.*)."""
    for key, values in scene.sweep.parameters.items():
        cls: Any = type(scene)
        parts = key.split(".")
        for i, part in enumerate(parts):
            where = ".".join(parts[:i]) or "the scene"
            if part not in cls.model_fields:
                if cls is type(scene.system):
                    where += f" ({scene.system.type})"
                raise PathError(f"sweep.parameters.{key}", values,
                                 f"'{part}' is not a key of {where}; allowed: {', '.join(cls.model_fields)}")
            if i == len(parts) - 1:
                break
            if cls is Scene and part == "system":
                cls = type(scene.system)
                continue
            sub = [t for t in annotation_types(cls.model_fields[part].annotation)
                   if isinstance(t, type) and issubclass(t, BaseModel)]
            if not sub:
                raise PathError(f"sweep.parameters.{key}", values,
                                 f"'{'.'.join(parts[:i + 1])}' is a value, not a section with keys")
            cls = sub[0]


NAME_MAX = 100          # characters: the output folder, its staging and lock names stay under 255 bytes
SCENE_FILE_MAX = 1 << 20   # bytes: larger scene files are refused unread


class Scene(Strict):
    """A loading study: system, friction coefficient, loading and the analyses wanted."""

    name: Annotated[str, Field(min_length=1, max_length=NAME_MAX)]
    system: Annotated[Union[registered_schemas()], Field(discriminator="type")]
    mu: NonNegFloat
    units: Literal["mm-N-MPa-tonne-s", "m-N-Pa-kg-s"] = Field(
        "mm-N-MPa-tonne-s", description="the consistent unit system the scene's numbers are in (labels only)")
    analyses: list[Analysis] = ["necessary", "sufficient", "mceip_mu", "mceip_lambda2"]
    mceip_lambda2_mu: Optional[NonNegFloat] = None
    loading: Optional[Loading] = None
    settings: Settings = Settings()
    sweep: Optional[Sweep] = None   # a batch of cases (app/study/sweep.py); None: one study
    outputs: Outputs = Outputs()    # files and pictures (app/io/, app/plot/); all off by default
    refinement: Optional[Refinement] = None   # a mesh-refinement study (app/study/refinement.py)
    transient: Optional[Transient] = None     # nonsmooth dynamics from chosen states (app/analyses/transient/)

    @field_validator("name")
    @classmethod
    def _name_is_folder_name(cls, v: str) -> str:
        # The name is the default output folder (output/<name>): one plain path component.
        if not re.fullmatch(r"[A-Za-z0-9_.\-]+", v) or set(v) == {"."}:
            raise ValueError("allowed: letters, digits, '_', '-' and '.' only (no spaces or slashes; "
                             "not just dots): the name is used as the output folder name")
        return v

    @field_validator("analyses")
    @classmethod
    def _unique(cls, v: list[str]) -> list[str]:
        dup = sorted({a for a in v if v.count(a) > 1})
        if dup:
            raise ValueError(f"each analysis may be listed once; listed twice: {', '.join(dup)}")
        return v

    @model_validator(mode="after")
    def _registered_system_checks(self) -> "Scene":
        hook = getattr(type(self.system), "check_scene", None)   # the system type's own checks (app/systems/)
        if hook is not None:
            hook(self)
        return self

    @model_validator(mode="after")
    def _outputs_match(self) -> "Scene":
        out = self.outputs
        if "first_mceip_mu" in out.states and "mceip_mu" not in self.analyses:
            raise PathError("outputs.states", out.states, "'first_mceip_mu' needs the analysis mceip_mu")
        return self

    @model_validator(mode="after")
    def _sweep_keys_exist(self) -> "Scene":
        if self.sweep is not None:
            _check_sweep_keys(self)
        return self

    @model_validator(mode="after")
    def _transient_needs_lambda2(self) -> "Scene":
        if self.transient is not None and "mceip_lambda2" not in self.analyses:
            raise PathError("transient", self.transient.model_dump(), "needs 'mceip_lambda2' in analyses (its "
                            "divergence modes start the dynamics and predict their growth)")
        return self

    @model_validator(mode="after")
    def _refinement_needs_a_mesh(self) -> "Scene":
        ref = self.refinement
        if ref is not None and not getattr(self.system, "refinable", False):
            raise PathError("refinement", ref.model_dump(), "needs a meshed body (a block, or a Gmsh body from a "
                                                            ".geo): it refines its mesh")
        if ref is not None and self.sweep is not None:
            raise PathError("refinement", ref.model_dump(), "cannot be combined with 'sweep': use one")
        if ref is not None:         # the levels this system type takes (app/systems/<type>/schema.py)
            key = self.system.refinement_key
            other = "size_factors" if key == "levels" else "levels"
            if getattr(ref, key) is None or getattr(ref, other) is not None:
                raise PathError(f"refinement.{key}", getattr(ref, key), f"this system's levels are '{key}' "
                                f"({self.system.refinement_help}), not '{other}'")
            problem = self.system.refinement_problem()
            if problem is not None:
                raise PathError("system.file", pathlib.Path(self.system.file).name, problem)
        return self

    @property
    def lambda2_mu(self) -> float:
        """Friction coefficient used by MCEIP-lambda^2 (the scene's mu unless overridden)."""
        return self.mu if self.mceip_lambda2_mu is None else self.mceip_lambda2_mu


def _keys_at(loc: tuple) -> list[str]:
    """The keys a scene allows at the mapping of location ``loc`` (pydantic's, with the system
    type's tag), for a suggestion; empty when it is not a mapping of known keys."""
    model: Any = Scene
    for part in loc:
        if isinstance(part, str) and part in SYSTEM_TYPES:
            model = SYSTEM_TYPES[part].schema
            continue
        field = getattr(model, "model_fields", {}).get(part)
        if field is None:
            return []
        model = _model_in(field.annotation)
        if model is None and part != "system":
            return []
    fields = getattr(model, "model_fields", {})
    return [f.alias or name for name, f in fields.items()]


def _model_in(annotation) -> Any:
    """The pydantic model an annotation holds (through Optional and Annotated), else None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in getattr(annotation, "__args__", ()) or ():
        found = _model_in(arg)
        if found is not None:
            return found
    meta = getattr(annotation, "__origin__", None)
    return _model_in(meta) if isinstance(meta, type) and issubclass(meta, BaseModel) else None


def _did_you_mean(e: dict) -> str | None:
    """``did you mean 'x'?`` for an unknown key close to an allowed one."""
    loc = tuple(e["loc"])
    if not loc or not isinstance(loc[-1], str):
        return None
    keys = {k.lower(): k for k in _keys_at(loc[:-1])}
    close = difflib.get_close_matches(loc[-1].lower(), list(keys), n=1, cutoff=0.6)
    return f"did you mean '{keys[close[0]]}'?" if close else None


def format_error(err: ValidationError) -> str:
    """The one-line message of a pydantic validation error: key path, bad value, what is allowed.
    An unknown key close to an allowed one is named first, with the key it probably is (a
    misspelt required key is also missing: "did you mean" says more than "missing")."""
    errors = err.errors(include_url=False)
    typo = next(((e, hint) for e in errors if e["type"] == "extra_forbidden" and (hint := _did_you_mean(e))), None)
    e = typo[0] if typo else errors[0]
    # Drop the discriminator tag pydantic inserts in the location of tagged unions.
    loc = [one_line(str(p)) for p in e["loc"] if p not in SYSTEM_TYPES]
    path = ".".join(loc) if loc else "(top level)"
    msg = e["msg"]
    value = e.get("input")
    if e["type"] == "extra_forbidden":
        hint = typo[1] if typo else None
        return f"unknown key '{path}' (not allowed here; {hint or 'check the spelling'})"
    if e["type"] == "missing":
        return f"missing key '{path}'"
    if e["type"] == "invalid_key":
        where = ".".join(loc[:-1]) or "(top level)"
        return f"{where}: key {show_value(value)} is not allowed: keys must be strings (names)"
    if e["type"] == "union_tag_invalid":
        tag = value.get("type") if isinstance(value, dict) else value
        return f"{path}.type = {show_value(tag)}: allowed types are {_system_types()}"
    if e["type"] == "union_tag_not_found":
        return f"missing key '{path}.type' (allowed: {_system_types()})"
    cause = (e.get("ctx") or {}).get("error")
    if isinstance(cause, PathError):
        path = ".".join(loc + [cause.path] if cause.path else loc) if loc else cause.path
        return f"{path} = {show_value(cause.value)}: {cause.msg}"
    if e["type"] in ("model_type", "model_attributes_type", "dict_type"):
        msg = "allowed: a mapping of keys (key: value, or {key: value, ...})"
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    bounds = {"less_than_equal": ("le", "less than or equal to"), "greater_than_equal": ("ge", "greater than or equal to"),
              "less_than": ("lt", "less than"), "greater_than": ("gt", "greater than")}
    limit = (e.get("ctx") or {}).get(bounds[e["type"]][0]) if e["type"] in bounds else None
    if isinstance(limit, float) and abs(limit) >= 1e16:
        msg = f"Input should be {bounds[e['type']][1]} {limit:g}"      # 1e+100, not pydantic's 101 digits
    return f"{path} = {show_value(value)}: {one_line(msg)}"


def _system_types() -> str:
    return ", ".join(f"'{t}'" for t in SYSTEM_TYPES)


def _limits_of(data: dict) -> Limits | None:
    """The scene's ``settings.limits``, validated ahead of the system (which reads its files under
    them); None when absent or invalid (the full validation reports it)."""
    settings = data.get("settings")
    raw = settings.get("limits") if isinstance(settings, dict) else None
    if raw is None:
        return None
    try:
        return Limits.model_validate(raw)
    except (ValidationError, ValueError, TypeError, RecursionError):
        return None


def scene_context(data: dict, base_dir, files: bool = True) -> dict:
    """The validation context of a scene document: the folder its paths are relative to, its
    ``settings.limits`` read ahead (the system reads its files under them), and whether it may
    name files at all (``files``: False for a scene stored in a results folder, which is data)."""
    return {"base_dir": base_dir, "limits": _limits_of(data), "files": files}


def parse_scene(data: Any, source: str = "scene", base_dir: str | pathlib.Path | None = None,
                files: bool = True) -> Scene:
    """Validate an already loaded YAML document; file paths in it are relative to ``base_dir``
    (the scene file's folder; default the current directory)."""
    if data is None:
        raise SceneError(f"{source}: the scene file is empty: it must be a YAML mapping with the keys "
                         f"name, system, mu (and optionally analyses, loading, settings)")
    if not isinstance(data, dict):
        raise SceneError(f"{source}: (top level) = {show_value(data)}: the scene must be a YAML mapping of keys "
                         f"(name, system, mu, ...), not a {type(data).__name__}")
    try:
        return Scene.model_validate(data, context=scene_context(data, base_dir, files))
    except ValidationError as err:
        cause = (err.errors(include_url=False)[0].get("ctx") or {}).get("error")
        raise SceneError(f"{source}: {format_error(err)}", 4 if isinstance(cause, ResourcePathError) else 2) from None
    except RecursionError:
        raise SceneError(f"{source}: the scene is nested too deeply") from None


class _UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing a key given twice in one mapping (YAML says keys are unique;
    PyYAML would silently keep the last value)."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict = {}
            for key_node, _ in node.value:
                if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                try:
                    key = self.construct_object(key_node, deep=False)
                    hash(key)
                except Exception:          # noqa: BLE001 - reported by the normal construction below
                    continue
                if key in seen:
                    raise SceneError(f"duplicate key {show_value(key)}: given at line {seen[key] + 1} and again "
                                     f"at line {key_node.start_mark.line + 1} (each key once per mapping)")
                seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor("tag:yaml.org,2002:map", _UniqueKeyLoader.construct_yaml_map)


def _read_scene_text(path: pathlib.Path) -> str:
    """The text of a regular scene file of at most SCENE_FILE_MAX bytes (others refused unread)."""
    import os
    import stat
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise SceneError(f"{path}: no such scene file") from None
    except IsADirectoryError:
        raise SceneError(f"{path}: is a folder, not a scene file") from None
    except OSError as err:
        raise SceneError(f"{path}: cannot read the scene file ({err.strerror or err})") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise SceneError(f"{path}: is a folder, not a scene file")
        if not stat.S_ISREG(st.st_mode):
            raise SceneError(f"{path}: not a regular file (a device, FIFO or socket): a scene must be a YAML file")
        if st.st_size > SCENE_FILE_MAX:
            raise SceneError(f"{path}: {st.st_size} bytes: a scene file may have at most {SCENE_FILE_MAX} bytes")
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(SCENE_FILE_MAX + 1)
    except OSError as err:
        raise SceneError(f"{path}: cannot read the scene file ({err.strerror or err})") from None
    finally:
        os.close(fd)
    if len(data) > SCENE_FILE_MAX:
        raise SceneError(f"{path}: a scene file may have at most {SCENE_FILE_MAX} bytes")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise SceneError(f"{path}: not UTF-8 text (byte 0x{err.object[err.start]:02x} at offset {err.start}): "
                         f"a scene file must be UTF-8 encoded YAML") from None


def with_overrides(data: Any, overrides: Sequence[str]) -> Any:
    """``data`` (a scene document) with each ``KEY=VALUE`` of ``overrides`` set: ``KEY`` a dotted
    path of keys (a number indexes a list: ``system.program.0.steps``), ``VALUE`` read as YAML
    (``0.8``, ``[1, 2]``, ``{E: 5.0, nu: 0.3}``); missing mappings on the way are created. The
    result is validated as the file is. Raises :class:`SceneError` with a one-line message."""
    for item in overrides:
        key, sep, text = item.partition("=")
        parts = key.strip().split(".")
        if not sep or not all(parts):
            raise SceneError(f"--set {item!r}: expected KEY=VALUE with a dotted key, e.g. --set mu=0.8 or "
                             "--set system.nx=40")
        try:
            value = yaml.load(text, Loader=_UniqueKeyLoader)     # noqa: S506 - a SafeLoader subclass
        except (yaml.YAMLError, SceneError, RecursionError, ValueError, TypeError) as err:
            raise SceneError(f"--set {item!r}: the value is not valid YAML ({one_line(str(err))})") from None
        if not isinstance(data, dict):
            raise SceneError(f"--set {item!r}: the scene is not a mapping")
        node: Any = data
        for i, part in enumerate(parts[:-1]):
            where = ".".join(parts[:i + 1])
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise SceneError(f"--set {item!r}: '{where}': the list has {len(node)} entries (0 to {len(node) - 1})")
                node = node[int(part)]
            elif isinstance(node, dict):
                node = node.setdefault(part, {})
            else:
                raise SceneError(f"--set {item!r}: '{'.'.join(parts[:i])}' is not a mapping or a list")
        last = parts[-1]
        if isinstance(node, list):
            if not last.isdigit() or int(last) >= len(node):
                raise SceneError(f"--set {item!r}: '{key}': the list has {len(node)} entries (0 to {len(node) - 1})")
            node[int(last)] = value
        elif isinstance(node, dict):
            node[last] = value
        else:
            raise SceneError(f"--set {item!r}: '{'.'.join(parts[:-1])}' is not a mapping or a list")
    return data


def load_scene(path: str | pathlib.Path, overrides: Sequence[str] = ()) -> Scene:
    """Read and validate a scene file, with the command line's ``--set KEY=VALUE`` ``overrides``
    applied first (:func:`with_overrides`). Raises :class:`SceneError` with a one-line message."""
    path = pathlib.Path(path)
    text = _read_scene_text(path)
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)   # noqa: S506 - a SafeLoader subclass
    except SceneError as err:
        raise SceneError(f"{path}: {err}") from None
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(err, "problem", None) or (str(err).splitlines() or [type(err).__name__])[0]
        raise SceneError(f"{path}: invalid YAML: {where}{problem}") from None
    except RecursionError:
        raise SceneError(f"{path}: invalid YAML: nested too deeply") from None
    except Exception as err:     # the YAML constructors' own errors, e.g. "!!int abc", over-long integers
        raise SceneError(f"{path}: invalid YAML: a value could not be converted "
                         f"({type(err).__name__}: {err})") from None
    if overrides:
        data = with_overrides(data, overrides)
    return parse_scene(data, str(path) + (" with --set" if overrides else ""), path.parent)


def default_scene_path() -> pathlib.Path:
    """The embedded default study (the paper's block)."""
    return pathlib.Path(__file__).parents[1] / "scenes" / "villechaise_block.yaml"
