"""The results.json format (version 3) as pydantic models: its JSON Schema and a validator.

``scripts/results_schema.py`` writes :func:`json_schema` to docs/results-schema.json (a test
checks it is not stale); :func:`validate` parses a results.json text with these models, strictly
(a number must be a JSON number, a string "inf" is refused). The models describe the document,
they do not build it (app/io/document.py writes it from the study's results): each record names
the keys every run writes and lets an analysis add its own (``additionalProperties``).

Every number is a JSON number; a non-finite one is ``null`` and listed in ``non_finite``
(:data:`Number`). Quantities are in the units of the top-level ``units`` block. This module
imports neither PETSc nor DOLFINx.
"""
from __future__ import annotations

from typing import Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field

from app.io.document import FORMAT_VERSION

#: a number of results.json: null when it is not finite (its value is in ``non_finite``)
Number = Optional[float]


class Record(BaseModel):
    """A record of results.json: the keys below, and possibly others."""

    model_config = ConfigDict(extra="allow")


class Units(Record):
    """Names of the units every quantity is given in (the scene's ``units``); labels, no conversion."""

    length: str
    force: str
    time: Optional[str] = None
    lambda2: str = Field(description="unit of lambda^2 (1/time^2)")
    mu: str = Field(description="friction coefficients: dimensionless, '1'")
    stiffness: Optional[str] = None
    mass: Optional[str] = None
    stress: Optional[str] = Field(None, description="meshed bodies only")
    density: Optional[str] = Field(None, description="meshed bodies only")


class Failure(Record):
    """A state whose loading or analysis failed (the CLI then exits with status 3)."""

    state: Optional[int] = None
    analysis: str
    reason: str


class PathInfo(Record):
    """How the loading path ended; the block's path also gives its normal phase."""

    end: str = Field(description="why the path ended (gross sliding, tangential_max reached, a failure, ...)")
    failure: Optional[Failure] = None
    normal_displacement: Number = Field(None, description="block: CD depth reaching the normal force [length]")
    normal_force: Number = Field(None, description="block: normal resultant at the end of the normal phase [force]")
    normal_steps: Optional[int] = None
    tangential_step: Number = Field(None, description="block: CD u_x increment [length]")


class Stage(Record):
    """One timed stage of the run."""

    name: str
    seconds: Number
    count: int


class NonFinite(Record):
    """Where results.json has null for a number that is not finite, and what that number is."""

    reason: str
    values: dict[str, Literal["+inf", "-inf", "nan"]] = Field(
        description="JSON pointer (RFC 6901) of each null number -> its value")


class Load(Record):
    """The load of a state (block: the CD displacement and the resultants; a program: its step)."""

    phase: Optional[str] = None
    u_x: Number = Field(None, description="CD displacement [length]")
    u_y: Number = Field(None, description="CD displacement [length]")
    normal_resultant: Number = Field(None, description="[force]")
    tangential_resultant: Number = Field(None, description="[force]")
    step: Optional[Any] = None
    parameters: Optional[dict[str, Any]] = None


class Classification(Record):
    """Contact nodes by status at a state."""

    free: int
    zero: int
    stick: int
    slip: int


class NodeRecord(Record):
    """A contact node (paper sign convention: u_N <= 0, r_N <= 0 compressive)."""

    id: int
    x: Number = Field(description="position along the contact line [length]")
    status: Literal["free", "zero", "stick", "slip"]
    sign: int = Field(description="slip direction S = sign(r_T) of a slip node, 0 otherwise")
    u_N: Number
    u_T: Number
    r_N: Number
    r_T: Number


class Certificate(Record):
    """What an analysis proved (or could not), and how."""

    status: str = Field(description="proven, not proven, ... (docs/proofs.md)")
    method: str
    rigorous: Optional[bool] = None
    interval: Optional[list[Number]] = Field(None, description="the interval of the claim (null end: infinity)")
    gap: Number = None
    seconds: Number = None
    detail: Optional[dict[str, Any]] = None


class Solution(Record):
    """One eigenvalue of an MCEIP (or a mode of the sufficient condition) and the evidence for it."""

    value: Number = Field(description="mu (MCEIP-mu) or lambda^2 [lambda2] (MCEIP-lambda^2)")
    x_Ts: list[Number] = Field(description="tangential rates of the slip nodes, A to B, summing to 1")
    pattern: list[Literal["slip", "stick"]] = Field(description="per slip node, A to B")
    residual: Number = None
    complementarity: Number = None
    min_x_Ts: Number = None
    min_y_Ts: Number = None
    iterations: Optional[int] = None
    found_by: Optional[list[str]] = None
    found_count: Optional[int] = None
    certified: Optional[bool] = None
    certificate: Optional[Certificate] = None
    enclosure: Optional[list[Number]] = None


class Status(Record):
    """Keys any analysis record may have instead of an answer."""

    failed: Optional[bool] = None
    reason: Optional[str] = None
    not_applicable: Optional[bool] = None


class Necessary(Status):
    """Necessary condition (19): smallest eigenvalues of sym K*(mu) and sym M*(mu)."""

    satisfied: Optional[bool] = None
    mu: Number = None
    min_eig_K_sym: Number = None
    min_eig_M_sym: Number = None


class Sufficient(Status):
    """Sufficient condition (17)-(18): admissible real lambda^2 > 0 with x_Ts >= 0."""

    satisfied: Optional[bool] = None
    mu: Number = None
    lambda2: Optional[list[Number]] = Field(None, description="[lambda2]")
    modes: Optional[list[Solution]] = None


class Onset(Record):
    """MCEIP-mu: the claim on the smallest critical mu (docs/proofs.md)."""

    status: str
    proven: bool
    value: Number = None
    enclosure: Optional[list[Number]] = None


class Complete(Record):
    """MCEIP-mu: the claim that the list of solutions is complete on an interval."""

    status: str
    proven: bool
    count: Optional[int] = None
    interval: Optional[list[Number]] = None


class Mceip(Status):
    """An MCEIP analysis: its solutions, how they were searched for, and what is proven."""

    problem: Optional[str] = None
    method: Optional[str] = None
    result: Optional[str] = Field(None, description="the one-line answer")
    mu: Number = Field(None, description="MCEIP-lambda^2: the friction coefficient")
    solutions: Optional[list[Solution]] = None
    search: Optional[dict[str, Any]] = Field(None, description="how the search was bounded ('complete': a proof)")
    certified: Optional[bool] = None
    certificate: Optional[Certificate] = None


class MceipMu(Mceip):
    """MCEIP-mu (21)-(23) at a state."""

    onset: Optional[Onset] = None
    complete: Optional[Complete] = None


class Enumerate(Mceip):
    """Exhaustive enumeration of the stick/slip patterns (small s)."""

    complete: Optional[bool] = None
    problems: Optional[dict[str, Mceip]] = None


class Analyses(Record):
    """The analyses of a state (shared by the states of one classification)."""

    necessary: Optional[Necessary] = None
    sufficient: Optional[Sufficient] = None
    mceip_mu: Optional[MceipMu] = None
    mceip_lambda2: Optional[Mceip] = None
    enumerate: Optional[Enumerate] = None


class State(Record):
    """One equilibrium state of the loading path."""

    index: int
    load: Load
    classification: Classification
    nodes: list[NodeRecord]
    analyses: Analyses
    analyses_shared_with: Optional[int] = Field(description="state whose analyses these are; null: computed here")
    analysis_seconds: Number = None
    contact_solve: Optional[dict[str, Any]] = Field(None, description="how the contact increment was solved")


class ModeField(Record):
    """A mode whose field was written (ParaView, fields.npz) and how its shape was built."""

    name: str
    built: str


class OutputsRecord(Record):
    """The fields and pictures a run made (with the scene's ``outputs``)."""

    notes: list[str] = Field(default_factory=list, description="what was left out or failed, in words")
    files: list[str] = Field(default_factory=list, description="files written, relative to the results folder")
    pictured_states: Optional[list[int]] = None
    modes: Optional[list[ModeField]] = None
    fields_not_applicable: Optional[str] = Field(None, description="why the system has no fields (no mesh)")


class ResultsDocument(Record):
    """results.json, format 3 (docs/outputs.md).

    Every number is a JSON number; one that is not finite (an infinite interval end, say) is null,
    and ``non_finite`` lists it by its JSON pointer with its value. Quantities are in the units of
    ``units``; no key name carries a unit. Records may hold keys beyond those listed here.
    """

    model_config = ConfigDict(extra="allow", title="results.json")

    format_version: Literal[FORMAT_VERSION]
    scene: str
    units: Units
    system: str = Field(description="the system, in words")
    mu: Number = Field(description="the scene's friction coefficient")
    analyses_requested: list[str]
    path: PathInfo
    distinct_classifications: int
    stages: list[Stage]
    failures: list[Failure]
    warnings: list[str]
    mpi_ranks: int
    wall_seconds: Number
    scene_config: dict[str, Any] = Field(description="the validated scene with its defaults (docs/scene-keys.md)")
    outputs: Optional[OutputsRecord] = Field(None, description="fields and pictures made (with outputs:)")
    versions: Optional[dict[str, str]] = Field(None, description="software versions (runs with outputs)")
    library_warnings: Optional[list[Any]] = Field(None, description="warnings of libraries, each kind once")
    sweep_case: Optional[dict[str, Any]] = Field(None, description="a case of a sweep: its name, values and hash")
    inspection: Optional[dict[str, Any]] = Field(None, description="a refinement level's own measurements")
    non_finite: Optional[NonFinite] = None
    states: list[State]


def json_schema() -> dict:
    """The JSON Schema of results.json (docs/results-schema.json)."""
    schema = ResultsDocument.model_json_schema(mode="validation")
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **schema}


def validate(text: str) -> ResultsDocument:
    """Parse a results.json text with the models, strictly; raises pydantic.ValidationError."""
    return ResultsDocument.model_validate_json(text, strict=True)
