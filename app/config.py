"""Scene files: YAML validated by pydantic into typed, frozen objects.

A scene names the system, the friction coefficient, the loading (for the FE block) and the
analyses wanted. Validation errors become one line naming the key path, the bad value and what
is allowed (:class:`SceneError`); the CLI prints that line and exits with status 2.
"""
from __future__ import annotations

import pathlib
from typing import Annotated, Any, Literal, Optional, Union

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

ANALYSES = ("necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate")
Analysis = Literal["necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"]


class SceneError(Exception):
    """A user mistake in a scene file: ``str(err)`` is the one-line message."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


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
        if isinstance(v, (list, tuple)):
            for s in v:
                if isinstance(s, bool) or not isinstance(s, int):
                    raise ValueError("each sign must be the integer -1 or 1")
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
            raise ValueError("pattern 'unstructured' needs mesh_size (a positive length in mm)")
        return self


class Loading(_Strict):
    """Quasi-static loading of the block: press CD down, then drag it to the left. N and mm."""
    normal_force: PosFloat = 55.0
    normal_steps: Annotated[int, Field(ge=1, le=10000)] = 10
    tangential_step: PosFloat = 0.02
    tangential_max: PosFloat = 10.0


class McpSettings(_Strict):
    """Search settings for the MCPs of Propositions 1-2 (PETSc SNES VI)."""
    rtol: Annotated[float, Field(gt=0, lt=1)] = 1e-12
    max_it: Annotated[int, Field(ge=1, le=10000)] = 100
    accept_tol: Annotated[float, Field(gt=0, lt=1)] = 1e-8
    starts: Annotated[list[PosFloat], Field(min_length=1)] = [0.5, 2.0, 10.0, 100.0]
    shift_rounds: Annotated[int, Field(ge=0, le=100)] = 6
    pattern_starts: bool = True
    pattern_eig_limit: Annotated[int, Field(ge=0)] = 300


class EigSettings(_Strict):
    """SLEPc settings for the necessary and sufficient conditions."""
    dense_limit: Annotated[int, Field(ge=1)] = 4000
    nev: Annotated[int, Field(ge=1)] = 30
    tol: Annotated[float, Field(gt=0, lt=1)] = 1e-10


class Settings(_Strict):
    classify_rtol: Annotated[float, Field(gt=0, lt=1)] = 1e-8
    mcp: McpSettings = McpSettings()
    eig: EigSettings = EigSettings()
    enumerate_max_slip: Annotated[int, Field(ge=1, le=24)] = 14
    enumerate_problems: list[Literal["mu", "lambda2"]] = ["mu", "lambda2"]
    mceip_mu_method: Literal["condensed", "full"] = "condensed"


class Scene(_Strict):
    """A loading study: system, friction coefficient, loading and the analyses wanted."""
    name: Annotated[str, Field(min_length=1, pattern=r"^[A-Za-z0-9_.\-]+$")]
    system: Annotated[Union[TwoParticles, Block], Field(discriminator="type")]
    mu: NonNegFloat
    analyses: list[Analysis] = ["necessary", "sufficient", "mceip_mu", "mceip_lambda2"]
    mceip_lambda2_mu: Optional[NonNegFloat] = None
    loading: Optional[Loading] = None
    settings: Settings = Settings()

    @field_validator("analyses")
    @classmethod
    def _unique(cls, v: list[str]) -> list[str]:
        dup = sorted({a for a in v if v.count(a) > 1})
        if dup:
            raise ValueError(f"analyses listed twice: {', '.join(dup)}")
        return v

    @model_validator(mode="after")
    def _loading_matches_system(self) -> "Scene":
        if isinstance(self.system, Block) and self.loading is None:
            object.__setattr__(self, "loading", Loading())
        if isinstance(self.system, TwoParticles) and self.loading is not None:
            raise ValueError("a two_particles system is a single equilibrium state: remove 'loading'")
        return self

    @property
    def lambda2_mu(self) -> float:
        """Friction coefficient used by MCEIP-lambda^2 (the scene's mu unless overridden)."""
        return self.mu if self.mceip_lambda2_mu is None else self.mceip_lambda2_mu


def _format_error(err: ValidationError) -> str:
    e = err.errors(include_url=False)[0]
    # Drop the discriminator tag pydantic inserts in the location of tagged unions.
    loc = [str(p) for p in e["loc"] if p not in ("two_particles", "block")]
    path = ".".join(loc) if loc else "(top level)"
    msg = e["msg"]
    if e["type"] == "extra_forbidden":
        return f"unknown key '{path}' (not allowed here; check the spelling)"
    if e["type"] == "missing":
        return f"missing key '{path}'"
    if e["type"] == "union_tag_invalid":
        return f"{path}.type = {e['input'].get('type')!r}: allowed types are 'two_particles', 'block'"
    if e["type"] == "union_tag_not_found":
        return f"missing key '{path}.type' (allowed: 'two_particles', 'block')"
    value = e.get("input")
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    return f"{path} = {value!r}: {msg}"


def parse_scene(data: Any, source: str = "scene") -> Scene:
    """Validate an already loaded YAML document."""
    if not isinstance(data, dict):
        raise SceneError(f"{source}: the scene must be a YAML mapping of keys, got {type(data).__name__}")
    try:
        return Scene.model_validate(data)
    except ValidationError as err:
        raise SceneError(f"{source}: {_format_error(err)}") from None


def load_scene(path: str | pathlib.Path) -> Scene:
    """Read and validate a scene file. Raises :class:`SceneError` with a one-line message."""
    path = pathlib.Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneError(f"{path}: no such scene file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f"{path}: cannot read the scene file ({err.__class__.__name__}: {err})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise SceneError(f"{path}: invalid YAML: {where}{problem}") from None
    return parse_scene(data, str(path))


def default_scene_path() -> pathlib.Path:
    """The embedded default study (the paper's block)."""
    return pathlib.Path(__file__).parent / "scenes" / "villechaise_block.yaml"
