"""Scene files: YAML validated by pydantic into typed, frozen objects.

A scene names the system, the friction coefficient, the loading (for the FE block) and the
analyses wanted. Validation errors become one line naming the key path, the bad value and what
is allowed (:class:`SceneError`); the CLI prints that line and exits with status 2.
"""
from __future__ import annotations

import pathlib
import re
import reprlib
from typing import Annotated, Any, Literal, Optional, Union

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from app.systems import SYSTEM_TYPES  # system types beyond block/two_particles
from app.systems import schemas as registered_schemas
from app.systems.schema import SystemPathError

ANALYSES = ("necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate")
Analysis = Literal["necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"]


class SceneError(Exception):
    """A user mistake in a scene file: ``str(err)`` is the one-line message."""

    def __init__(self, msg: str):
        super().__init__(_one_line(msg))


def _one_line(text: str) -> str:
    """``text`` with every line break (as ``str.splitlines`` sees them) replaced by a space."""
    return " ".join(text.splitlines()) if text else text


class _PathError(ValueError):
    """A model-level check that blames one key: ``path`` is relative to the model validated."""

    def __init__(self, path: str, value: Any, msg: str):
        super().__init__(msg)
        self.path, self.value, self.msg = path, value, msg


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxdict, _REPR.maxlist, _REPR.maxtuple = 2, 6, 6, 6
_REPR.maxset = _REPR.maxfrozenset = 6
_REPR.maxstring, _REPR.maxlong, _REPR.maxother = 60, 40, 60


def _show(value: Any) -> str:
    """A short one-line repr of a user value (bounded: YAML aliases can build huge or cyclic values)."""
    try:
        text = _REPR.repr(value)
    except Exception:                      # e.g. ints beyond the int-to-str digit limit
        text = f"<{type(value).__name__}>"
    text = _one_line(text)
    return text if len(text) <= 160 else text[:150] + "...(cut)"


def _is_numeric_annotation(tp: Any) -> bool:
    """The annotation takes numbers (int/float) and no booleans (``mu: yes`` must not become 1.0)."""
    return _number_kind(tp) is not None


def _number_kind(tp: Any) -> str | None:
    """'an integer' or 'a number' if the annotation takes numbers and no booleans, else None."""
    import typing
    found = {"int": False, "float": False, "bool": False}

    def walk(t: Any) -> None:
        if t is bool or t is str or (isinstance(t, type) and issubclass(t, BaseModel)):
            found["bool"] = True           # mixed with non-numbers: the field's own validator decides
        elif t is int:
            found["int"] = True
        elif t is float:
            found["float"] = True
        elif typing.get_origin(t) is Literal:
            for a in typing.get_args(t):
                if isinstance(a, (bool, str)):
                    found["bool"] = True
                elif isinstance(a, int):
                    found["int"] = True
                elif isinstance(a, float):
                    found["float"] = True
        else:
            for a in typing.get_args(t):
                walk(a)
    walk(tp)
    if found["bool"] or not (found["int"] or found["float"]):
        return None
    return "a number" if found["float"] else "an integer"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)

    @model_validator(mode="before")
    @classmethod
    def _no_booleans_for_numbers(cls, data: Any) -> Any:
        """Booleans are not numbers: YAML's ``yes``/``true`` would silently become 1."""
        if isinstance(data, dict):
            for name, v in data.items():
                field = cls.model_fields.get(name) if isinstance(name, str) else None
                kind = _number_kind(field.annotation) if field is not None else None
                if kind is None:
                    continue
                if isinstance(v, bool) or (isinstance(v, (list, tuple)) and any(isinstance(x, bool) for x in v)):
                    raise _PathError(name, v, f"a boolean (true/false/yes/no/on/off) is not a number: "
                                              f"allowed: {kind}" + (" (or a list of them)" if isinstance(v, (list, tuple)) else ""))
        return data


PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class TwoParticles(_Strict):
    """The two-particle system of the paper, section 5, Fig. 1 (DESIGN.md section 4)."""
    type: Literal["two_particles"]
    k: PosFloat = Field(description="spring stiffness [N/mm]")
    m: PosFloat = Field(description="particle mass [tonne]")
    phi_deg: Annotated[float, Field(gt=0, lt=90, allow_inf_nan=False)] = Field(
        description="angle of the inclined springs with the horizontal [deg]")
    signs: tuple[Literal[-1, 1], Literal[-1, 1]] = Field(
        description="S1, S2: signs of the static tangential reactions (both particles in impending slip)")

    @field_validator("signs", mode="before")
    @classmethod
    def _signs_are_ints(cls, v: Any) -> Any:
        if (not isinstance(v, (list, tuple)) or len(v) != 2
                or any(isinstance(s, bool) or not isinstance(s, int) or s not in (-1, 1) for s in v)):
            raise ValueError("allowed: a list of two signs [S1, S2], each the integer -1 or 1")
        return v


class Block(_Strict):
    """The elastic block of Villechaise and Zeghloul (DESIGN.md section 5). Units: mm, MPa, tonne/mm^3."""
    type: Literal["block"]
    length: PosFloat = 80.0
    height: PosFloat = 40.0
    thickness: PosFloat = 9.6
    nx: Annotated[int, Field(ge=1, le=4096)] = 20
    ny: Annotated[int, Field(ge=1, le=4096)] = 10
    pattern: Literal["crossed", "right", "left", "alternate", "unstructured"] = "crossed"
    mesh_size: Optional[PosFloat] = None
    degree: Literal[1, 2] = 1
    plane: Literal["stress", "strain"] = "stress"
    E: PosFloat = 5.0
    nu: Annotated[float, Field(gt=-1.0, lt=0.5, allow_inf_nan=False)] = 0.48
    density: PosFloat = 1.2e-9
    mass: Literal["consistent", "lumped"] = "consistent"

    @model_validator(mode="after")
    def _mesh_size_for_unstructured(self) -> "Block":
        if self.pattern == "unstructured" and self.mesh_size is None:
            raise _PathError("mesh_size", None, "pattern 'unstructured' needs mesh_size (a positive length in mm)")
        return self


class Loading(_Strict):
    """Quasi-static loading of the block: press CD down, then drag it to the left. N and mm."""
    normal_force: PosFloat = 55.0
    normal_steps: Annotated[int, Field(ge=1, le=10000)] = 10
    tangential_step: PosFloat = 0.02
    tangential_max: PosFloat = 10.0


class Limits(_Strict):
    """Resource limits checked before any work starts (app/preflight.py); raise them deliberately."""
    max_states: Annotated[int, Field(ge=1, le=10**9)] = Field(
        100_000, description="most load states (normal_steps + tangential_max / tangential_step)")
    max_dofs: Annotated[int, Field(ge=1, le=10**9)] = Field(2_000_000, description="most DOFs of the block mesh")
    max_contact_nodes: Annotated[int, Field(ge=1, le=10**7)] = Field(
        20_000, description="most contact nodes on AB")
    max_memory_gb: Optional[Annotated[float, Field(gt=0, le=1e6, allow_inf_nan=False)]] = Field(
        None, description="largest memory estimate accepted [GiB]; null: 80 % of the machine's RAM")


class McpSettings(_Strict):
    """Search settings for the MCPs of Propositions 1-2 (PETSc SNES VI)."""
    rtol: Annotated[float, Field(gt=0, lt=1)] = 1e-12
    max_it: Annotated[int, Field(ge=1, le=10000)] = 50
    stol: Annotated[float, Field(ge=0, lt=1)] = 1e-10
    accept_tol: Annotated[float, Field(gt=0, lt=1)] = 1e-8
    starts: Annotated[list[Annotated[float, Field(gt=0, le=1e12, allow_inf_nan=False)]],
                      Field(min_length=1, max_length=100)] = [0.5, 2.0, 10.0, 100.0]
    shift_rounds: Annotated[int, Field(ge=0, le=100)] = 6
    pattern_starts: bool = True
    pattern_eig_limit: Annotated[int, Field(ge=0, le=100_000)] = 300
    rsls_linesearch: Literal["bt", "basic", "l2", "cp"] = "bt"
    # a SNES VI run whose residual has not halved in this many iterations is stopped as failed (0: off)
    stagnation_its: Annotated[int, Field(ge=0, le=10000)] = 10
    # Certificates for the condensed MCEIP-mu (app/analyses/certify.py, DESIGN.md section 7):
    # every critical mu up to the cap is proven; the cap is mu_cap, or mu_cap_factor x the scene's mu.
    certify: bool = True
    mu_cap: Optional[PosFloat] = None
    mu_cap_factor: PosFloat = 10.0
    certify_seconds: PosFloat = 60.0            # per-state budget: an unfinished proof says so
    certify_enumerate_max: Annotated[int, Field(ge=0, le=20)] = 12   # enumeration up to here, SCIP above
    # MCEIP-lambda^2: exact slip-node reduction through the dense (K, M) eigen-decomposition, used to
    # prove "no solution" up to this many DOFs (app/analyses/lambda2_exact.py); SNES VI search otherwise
    lambda2_exact_max_dofs: Annotated[int, Field(ge=0, le=20_000)] = 1500
    # condensed MCEIP-mu search: above this many slip nodes the "x zero on one node" starts (nearly
    # uniform there) are left out, half the Newton runs (app/analyses/dense_mcp.py)
    search_zero_one_max: Annotated[int, Field(ge=0, le=100_000)] = 40


class EigSettings(_Strict):
    """SLEPc settings for the necessary and sufficient conditions."""
    dense_limit: Annotated[int, Field(ge=1, le=10_000)] = 500
    nev: Annotated[int, Field(ge=1, le=1000)] = 30
    tol: Annotated[float, Field(gt=0, lt=1)] = 1e-10
    max_it: Annotated[int, Field(ge=1, le=1_000_000)] = 1000


class Settings(_Strict):
    classify_rtol: Annotated[float, Field(gt=0, lt=1)] = 1e-8
    mcp: McpSettings = McpSettings()
    eig: EigSettings = EigSettings()
    enumerate_max_slip: Annotated[int, Field(ge=1, le=24)] = 14
    enumerate_problems: Annotated[list[Literal["mu", "lambda2"]], Field(max_length=2)] = ["mu", "lambda2"]
    mceip_mu_method: Literal["condensed", "full"] = "condensed"
    limits: Limits = Field(Limits(), description="resource limits checked before any work (README, Safety)")


_SWEEP_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")
_SWEEP_MAX_VALUES = 10000


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _sweep_range(key: str, spec: dict) -> list:
    """Values of a range ``{start, stop, num}`` (evenly spaced, both ends included) or
    ``{start, stop, step}`` (start, start + step, ... up to stop); integers stay integers."""
    allowed = "a range is {start, stop, num} or {start, stop, step} (stop included)"
    extra = sorted(str(k) for k in spec if k not in ("start", "stop", "num", "step"))
    if extra:
        raise _PathError(key, spec, f"unknown range key '{extra[0]}': {allowed}")
    if "start" not in spec or "stop" not in spec or ("num" in spec) == ("step" in spec):
        raise _PathError(key, spec, allowed)
    start, stop = spec["start"], spec["stop"]
    if not (_is_number(start) and _is_number(stop) and all(abs(v) <= 1e300 for v in (start, stop))):
        raise _PathError(key, spec, f"start and stop must be finite numbers: {allowed}")
    if "num" in spec:
        num = spec["num"]
        if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= _SWEEP_MAX_VALUES:
            raise _PathError(key, spec, f"num must be an integer from 1 to {_SWEEP_MAX_VALUES}")
        if num == 1 and start != stop:
            raise _PathError(key, spec, "num = 1 needs start = stop (a single value)")
        raw = [float(start) + (float(stop) - float(start)) * i / max(num - 1, 1) for i in range(num)]
        ints = isinstance(start, int) and isinstance(stop, int)
    else:
        step = spec["step"]
        if not _is_number(step) or not 0 < step <= 1e300:
            raise _PathError(key, spec, "step must be a positive number (it goes from start towards stop)")
        count = abs(float(stop) - float(start)) / float(step)
        if not count < _SWEEP_MAX_VALUES:
            raise _PathError(key, spec, f"more than {_SWEEP_MAX_VALUES} values")
        count = int(count + 1e-9) + 1
        sign = 1 if stop >= start else -1
        raw = [float(start) + sign * float(step) * i for i in range(count)]
        ints = all(isinstance(v, int) for v in (start, stop, step))
    # round away the binary noise of the arithmetic (0.30000000000000004 -> 0.3): stable case names
    out = [float(f"{v:.12g}") for v in raw]
    return [int(v) for v in out] if ints and all(v == int(v) for v in out) else out


class Sweep(_Strict):
    """A batch of studies: the scene with ``parameters`` (dotted key paths into the scene, e.g.
    ``system.length``) set to each of their values; ``product`` runs every combination, ``zip``
    runs the i-th values together. Values: a list, or a range {start, stop, num|step}."""
    mode: Literal["product", "zip"] = "product"
    parameters: dict[str, list[Any]]

    @field_validator("parameters", mode="before")
    @classmethod
    def _expand(cls, v: Any) -> Any:
        if not isinstance(v, dict) or not v:
            raise ValueError("allowed: a mapping of one or more dotted scene keys to their values, "
                             "e.g. {mu: [0.8, 1.1], system.length: {start: 40, stop: 120, num: 5}}")
        out = {}
        for key, values in v.items():
            if not isinstance(key, str) or not _SWEEP_KEY.fullmatch(key):
                raise _PathError(_one_line(str(key)), values, "a swept key must be a dotted path of scene keys, "
                                 "e.g. mu or system.length")
            if key.split(".")[0] in ("name", "sweep"):
                raise _PathError(key, values, "cannot be swept (the case names and the output folders are "
                                 "made from the swept values)")
            if isinstance(values, dict):
                values = _sweep_range(key, values)
            if not isinstance(values, (list, tuple)) or not values:
                raise _PathError(key, values, "allowed: a non-empty list of values [v1, v2, ...] or a range "
                                 "{start, stop, num} or {start, stop, step}")
            if len(values) > _SWEEP_MAX_VALUES:
                raise _PathError(key, values, f"more than {_SWEEP_MAX_VALUES} values")
            for x in values:
                if not (x is None or isinstance(x, (bool, int, float, str)) or (
                        isinstance(x, (list, tuple)) and all(isinstance(y, (bool, int, float, str)) for y in x))):
                    raise _PathError(key, values, f"the value {_show(x)} is not allowed: values are numbers, strings, "
                                     "booleans or lists of them (sweep the keys inside a section, e.g. system.nx)")
            seen: set = set()
            dup = sorted({n for n in map(repr, values) if n in seen or seen.add(n)})
            if dup:
                raise _PathError(key, values, f"each value may be listed once; listed twice: {', '.join(dup)}")
            out[key] = list(values)
        for a in out:
            for b in out:
                if b.startswith(a + "."):
                    raise _PathError(b, out[b], f"inside the swept key '{a}': sweep one or the other")
        return out

    @model_validator(mode="after")
    def _sizes(self) -> "Sweep":
        sizes = {k: len(v) for k, v in self.parameters.items()}
        if self.mode == "zip" and len(set(sizes.values())) > 1:
            raise _PathError("parameters", sizes, "mode 'zip' needs the same number of values for every key "
                             "(numbers of values shown)")
        total = 1
        for n in sizes.values():
            total = n if self.mode == "zip" else total * n
        if total > _SWEEP_MAX_VALUES:
            raise _PathError("parameters", sizes, f"{total} cases (numbers of values shown): "
                             f"at most {_SWEEP_MAX_VALUES} per sweep")
        return self


def _check_sweep_keys(scene: "Scene") -> None:
    """Every swept key must name a key of the scene's schema (the system's, for system.*)."""
    for key, values in scene.sweep.parameters.items():
        cls: Any = type(scene)
        parts = key.split(".")
        for i, part in enumerate(parts):
            where = ".".join(parts[:i]) or "the scene"
            if part not in cls.model_fields:
                if cls in (Block, TwoParticles):
                    where += f" ({scene.system.type})"
                raise _PathError(f"sweep.parameters.{key}", values,
                                 f"'{part}' is not a key of {where}; allowed: {', '.join(cls.model_fields)}")
            if i == len(parts) - 1:
                break
            if cls is Scene and part == "system":
                cls = type(scene.system)
                continue
            sub = [t for t in _annotation_types(cls.model_fields[part].annotation)
                   if isinstance(t, type) and issubclass(t, BaseModel)]
            if not sub:
                raise _PathError(f"sweep.parameters.{key}", values,
                                 f"'{'.'.join(parts[:i + 1])}' is a value, not a section with keys")
            cls = sub[0]


STATE_WORDS = ("final", "first_mceip_mu", "all_distinct")
_STATE_ALLOWED = ("allowed: a state index (an integer >= 0), 'final', 'first_mceip_mu', 'all_distinct', or node "
                  "counts selecting the first state that has them, e.g. {stick: 2, slip: 15, free: 4}")


class StateCounts(_Strict):
    """The first state whose node counts equal every count given, e.g. {stick: 2, slip: 15, free: 4}."""
    stick: Optional[Annotated[int, Field(ge=0)]] = None
    slip: Optional[Annotated[int, Field(ge=0)]] = None
    free: Optional[Annotated[int, Field(ge=0)]] = None
    zero: Optional[Annotated[int, Field(ge=0)]] = None


class Screenshots(_Strict):
    """Off-screen pyvista pictures of the block (app/outputs/screenshots.py)."""
    resolution: tuple[Annotated[int, Field(ge=100, le=8192)], Annotated[int, Field(ge=100, le=8192)]] = (1200, 800)
    field: Literal["displacement", "von_mises"] = "von_mises"
    modes: bool = True               # also draw every divergence mode found at the pictured states
    scale: PosFloat = 1.0            # magnification of the state displacements (modes are scaled to fit)


class Outputs(_Strict):
    """Files and pictures for people (app/outputs/); all off unless asked for."""
    paraview: bool = False           # XDMF time series of the states, VTU of the modes (block only)
    plots: bool = False              # matplotlib PNG + SVG
    report: bool = False             # report.md
    states: list[Union[Annotated[int, Field(ge=0, strict=True)], Literal["final", "first_mceip_mu", "all_distinct"],
                       StateCounts]] = ["final"]   # the states pictured (screenshots, reactions along AB)
    screenshots: Optional[Screenshots] = None     # true: the defaults (block only)

    @field_validator("screenshots", mode="before")
    @classmethod
    def _screenshots_bool(cls, v: Any) -> Any:
        return {} if v is True else (None if v is False else v)

    @field_validator("states", mode="before")
    @classmethod
    def _states(cls, v: Any) -> Any:
        if not isinstance(v, (list, tuple)) or not v:
            raise ValueError(f"allowed: a non-empty list of states; each is {_STATE_ALLOWED[9:]}")
        if len(v) > 1000:
            raise ValueError(f"{len(v)} states: at most 1000 may be pictured")
        for i, s in enumerate(v):
            if isinstance(s, bool) or not (isinstance(s, (int, dict)) or s in STATE_WORDS):
                raise _PathError(str(i), s, _STATE_ALLOWED)
            if isinstance(s, int) and s < 0:
                raise _PathError(str(i), s, _STATE_ALLOWED)
            if isinstance(s, dict):
                for key, n in s.items():
                    if key not in StateCounts.model_fields:
                        raise _PathError(f"{i}.{_one_line(str(key))}", s, "unknown node status: allowed keys are "
                                         "stick, slip, free, zero (node counts)")
                    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
                        raise _PathError(f"{i}.{key}", n, "allowed: a node count (an integer >= 0)")
                if not s:
                    raise _PathError(str(i), s, _STATE_ALLOWED)
        return v

    @property
    def fields(self) -> bool:
        """Displacement/stress/mode fields are needed (ParaView files or screenshots)."""
        return self.paraview or self.screenshots is not None

    @property
    def any(self) -> bool:
        return self.fields or self.plots or self.report


def _annotation_types(tp: Any) -> list:
    import typing
    args = typing.get_args(tp)
    return [tp] if not args else [t for a in args for t in _annotation_types(a)]


class Refinement(_Strict):
    """A mesh-refinement study of a block scene (app/refinement.py): the scene at every mesh level
    (nx cells along AB, ny = nx * height / length), every degree and every plane model."""
    levels: Annotated[list[Annotated[int, Field(ge=1, le=4096)]], Field(min_length=2, max_length=50)]
    degrees: Annotated[list[Literal[1, 2]], Field(min_length=1, max_length=2)] = [1]
    planes: Annotated[list[Literal["stress", "strain"]], Field(min_length=1, max_length=2)] = ["stress"]
    mu_fixed: Optional[NonNegFloat] = None     # mu of the sufficient condition at the final state
    resultant_at: PosFloat = 1.0               # |CD u_x| [mm] of the state whose resultants are compared
    first_solution: Literal["scan", "none"] = "scan"    # none: skip the search for the first solution
    max_contact_nodes: Optional[Annotated[int, Field(ge=2)]] = None   # skip levels with more (degree * nx + 1)

    @field_validator("levels", "degrees", "planes")
    @classmethod
    def _distinct(cls, v: list) -> list:
        if len(set(v)) != len(v):
            raise ValueError("each value may be listed once")
        return sorted(v) if v and isinstance(v[0], int) else v


NAME_MAX = 100          # characters: the output folder, its staging and lock names stay under 255 bytes
SCENE_FILE_MAX = 1 << 20   # bytes: larger scene files are refused unread


class Scene(_Strict):
    """A loading study: system, friction coefficient, loading and the analyses wanted."""
    name: Annotated[str, Field(min_length=1, max_length=NAME_MAX)]
    system: Annotated[Union[(TwoParticles, Block) + registered_schemas()], Field(discriminator="type")]
    mu: NonNegFloat
    units: Literal["mm-N-MPa-tonne-s", "m-N-Pa-kg-s"] = Field(
        "mm-N-MPa-tonne-s", description="the consistent unit system the scene's numbers are in (labels only)")
    analyses: list[Analysis] = ["necessary", "sufficient", "mceip_mu", "mceip_lambda2"]
    mceip_lambda2_mu: Optional[NonNegFloat] = None
    loading: Optional[Loading] = None
    settings: Settings = Settings()
    sweep: Optional[Sweep] = None   # a batch of cases (app/sweep.py); None: one study
    outputs: Outputs = Outputs()    # files and pictures (app/outputs/); all off by default
    refinement: Optional[Refinement] = None   # a mesh-refinement study (app/refinement.py)

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
    def _loading_matches_system(self) -> "Scene":
        if isinstance(self.system, Block) and self.loading is None:
            object.__setattr__(self, "loading", Loading())
        if isinstance(self.system, TwoParticles) and self.loading is not None:
            raise _PathError("loading", self.loading.model_dump(),
                             "not allowed for a two_particles system (a single equilibrium state): "
                             "remove 'loading', or use a block system")
        return self

    @model_validator(mode="after")
    def _registered_system_checks(self) -> "Scene":
        hook = getattr(type(self.system), "check_scene", None)   # registered types (app/systems/)
        if hook is not None:
            hook(self)
        return self

    @model_validator(mode="after")
    def _outputs_match(self) -> "Scene":
        out = self.outputs
        if isinstance(self.system, TwoParticles):
            for key in ("paraview", "screenshots"):
                if getattr(out, key):
                    raise _PathError(f"outputs.{key}", getattr(out, key) if key == "paraview" else True,
                                     "needs a mesh: not available for a two_particles system (use plots and report)")
        if "first_mceip_mu" in out.states and "mceip_mu" not in self.analyses:
            raise _PathError("outputs.states", out.states, "'first_mceip_mu' needs the analysis mceip_mu")
        return self

    @model_validator(mode="after")
    def _sweep_keys_exist(self) -> "Scene":
        if self.sweep is not None:
            _check_sweep_keys(self)
        return self

    @model_validator(mode="after")
    def _refinement_needs_block(self) -> "Scene":
        if self.refinement is not None and not isinstance(self.system, Block):
            raise _PathError("refinement", self.refinement.model_dump(), "needs a block system (it refines its mesh)")
        if self.refinement is not None and self.sweep is not None:
            raise _PathError("refinement", self.refinement.model_dump(), "cannot be combined with 'sweep': use one")
        return self

    @property
    def lambda2_mu(self) -> float:
        """Friction coefficient used by MCEIP-lambda^2 (the scene's mu unless overridden)."""
        return self.mu if self.mceip_lambda2_mu is None else self.mceip_lambda2_mu


def _format_error(err: ValidationError) -> str:
    e = err.errors(include_url=False)[0]
    # Drop the discriminator tag pydantic inserts in the location of tagged unions.
    loc = [_one_line(str(p)) for p in e["loc"] if p not in ("two_particles", "block", *SYSTEM_TYPES)]
    path = ".".join(loc) if loc else "(top level)"
    msg = e["msg"]
    value = e.get("input")
    if e["type"] == "extra_forbidden":
        return f"unknown key '{path}' (not allowed here; check the spelling)"
    if e["type"] == "missing":
        return f"missing key '{path}'"
    if e["type"] == "invalid_key":
        where = ".".join(loc[:-1]) or "(top level)"
        return f"{where}: key {_show(value)} is not allowed: keys must be strings (names)"
    if e["type"] == "union_tag_invalid":
        tag = value.get("type") if isinstance(value, dict) else value
        return f"{path}.type = {_show(tag)}: allowed types are {_system_types()}"
    if e["type"] == "union_tag_not_found":
        return f"missing key '{path}.type' (allowed: {_system_types()})"
    cause = (e.get("ctx") or {}).get("error")
    if isinstance(cause, (_PathError, SystemPathError)):
        path = ".".join(loc + [cause.path] if cause.path else loc) if loc else cause.path
        return f"{path} = {_show(cause.value)}: {cause.msg}"
    if e["type"] in ("model_type", "model_attributes_type", "dict_type"):
        msg = "allowed: a mapping of keys (key: value, or {key: value, ...})"
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    return f"{path} = {_show(value)}: {_one_line(msg)}"


def _system_types() -> str:
    return ", ".join(f"'{t}'" for t in ("two_particles", "block", *SYSTEM_TYPES))


def parse_scene(data: Any, source: str = "scene", base_dir: str | pathlib.Path | None = None) -> Scene:
    """Validate an already loaded YAML document; file paths in it are relative to ``base_dir``
    (the scene file's folder; default the current directory)."""
    if data is None:
        raise SceneError(f"{source}: the scene file is empty: it must be a YAML mapping with the keys "
                         f"name, system, mu (and optionally analyses, loading, settings)")
    if not isinstance(data, dict):
        raise SceneError(f"{source}: (top level) = {_show(data)}: the scene must be a YAML mapping of keys "
                         f"(name, system, mu, ...), not a {type(data).__name__}")
    try:
        return Scene.model_validate(data, context={"base_dir": base_dir} if base_dir is not None else None)
    except ValidationError as err:
        raise SceneError(f"{source}: {_format_error(err)}") from None
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
                    raise SceneError(f"duplicate key {_show(key)}: given at line {seen[key] + 1} and again "
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


def load_scene(path: str | pathlib.Path) -> Scene:
    """Read and validate a scene file. Raises :class:`SceneError` with a one-line message."""
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
    return parse_scene(data, str(path), path.parent)


def default_scene_path() -> pathlib.Path:
    """The embedded default study (the paper's block)."""
    return pathlib.Path(__file__).parent / "scenes" / "villechaise_block.yaml"
