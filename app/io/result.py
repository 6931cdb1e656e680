"""The typed result of a study: what ``results.json`` holds, described once.

A finished study (`app.study.run.study`, `app.run_study`) returns a
[`StudyResult`][app.io.result.StudyResult]; every output (results.json, steps.csv, the summary,
the plots, the report, the proofs, the fields) reads it. The models below are the one
description of the results.json format (version 3):

- results.json is serialised from them ([`StudyResult.to_json`][app.io.result.StudyResult.to_json]),
- a saved file is read back into them ([`StudyResult.load`][app.io.result.StudyResult.load],
  any format version),
- its JSON Schema is generated from them (:func:`json_schema`, docs/results-schema.json), and
  :func:`validate` checks a file strictly against them.

Each record names the keys every run writes and keeps any other key an analysis adds (the
solver's evidence, a system type's own load fields): they are read back and written again as
they were (``model_extra``). Arrays are numpy arrays (read-only); what a run keeps in memory only
(a mode's kept-space vector ``x``, the pencil and proof log of an MCEIP-mu proof ``proof``) is
never written.

The queries the outputs need ([`StudyResult.first_instability`][app.io.result.StudyResult.first_instability],
[`StateResult.min_mu`][app.io.result.StateResult.min_mu], [`StudyResult.final`][app.io.result.StudyResult.final],
[`StudyResult.state`][app.io.result.StudyResult.state], ...) are written here once.

Every number of the file is a JSON number; one that is not finite is ``null`` there and listed
in ``non_finite`` (app/io/document.py); in the models it is the float itself. Quantities are in
the units of ``units``. This module imports neither PETSc nor DOLFINx: it also reads results
saved by earlier runs.

Notation (the paper's, as in ``docs/method.md``): ``x_Ts`` is the tangential rate of the slip
nodes in a mode, normalised to sum 1, listed from A to B; ``pattern[i]`` is ``slip`` where
``x_Ts[i] > 0`` and ``stick`` where it is 0.
"""
from __future__ import annotations

import json
import math
import pathlib
from typing import Annotated, Any, Iterator, Literal, Optional, Union

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PlainSerializer,
    PlainValidator,
    WithJsonSchema,
    WrapSerializer,
    model_validator,
)
from pydantic.json_schema import SkipJsonSchema

from app.io.document import FORMAT_VERSION, from_document, to_document

#: keys of an MCEIP solution that are the evidence that it is one (app/analyses/snes_vi/search.py,
#: app/analyses/enumerate.py)
EVIDENCE_KEYS = ("residual", "complementarity", "min_x_Ts", "min_y_Ts", "iterations", "found_by",
                 "found_count", "relative_error")


class CriticalMu(float):
    """A critical friction coefficient of MCEIP-mu (21)-(23).

    It is a ``float`` with the full double-precision value (arithmetic, ``repr``, ``to_json``,
    format specs such as ``f"{mu:.10g}"`` all see every digit). Only ``str()`` (hence ``print``
    and ``f"{mu}"``) rounds, to 4 decimals: mu is dimensionless and the paper and the README
    quote it so (1.7048, 60.8058); the solver's accuracy is far better (acceptance 1e-8), the
    mesh error of the final value is about 3e-3 (README, refinement table).
    """

    def __str__(self) -> str:
        return f"{float(self):.4f}"


def _float(v: Any) -> float:
    """A number of the results (``None``: not a number; format 1's ``"inf"`` strings parse too)."""
    return math.nan if v is None else float(v)


def float_array(values: Any) -> np.ndarray:
    """Read-only float64 array of ``values`` (``None`` entries: NaN)."""
    if isinstance(values, np.ndarray) and values.dtype == np.float64 and values.ndim == 1:
        a = values.copy()
    else:
        if isinstance(values, (str, bytes)) or not isinstance(values, (list, tuple, np.ndarray)):
            raise ValueError("an array of numbers is expected")
        if any(isinstance(v, (str, bytes, bool)) for v in values):
            raise ValueError("an array of numbers is expected")
        a = np.asarray([_float(v) for v in values], dtype=np.float64)
    a.flags.writeable = False
    return a


def _array_json(a: np.ndarray) -> list:
    return [float(v) for v in a]


#: a vector of numbers (read-only float64; ``null`` entries of the file are NaN)
FloatArray = Annotated[np.ndarray, PlainValidator(float_array), PlainSerializer(_array_json, return_type=list),
                       WithJsonSchema({"type": "array", "items": {"type": ["number", "null"]}})]
def _listed(value, handler) -> list:
    return list(handler(value))


#: a sequence of the results: a tuple in the models, a list in results.json (and ``to_dict``)
AsList = WrapSerializer(_listed)
#: a number of results.json: null in the file when it is not finite (its value is in ``non_finite``)
Number = Optional[float]
#: what a run keeps in memory only: never written, never read from a file
InMemory = SkipJsonSchema[Any]


class Record(BaseModel):
    """A record of results.json: the keys below, and possibly others (kept as they are)."""

    model_config = ConfigDict(extra="allow", arbitrary_types_allowed=True)

    def to_dict(self) -> dict:
        """The record as it is written (before non-finite numbers become ``null``)."""
        return self.model_dump(mode="python", exclude_unset=True)


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

    phase: Union[str, int, None] = Field(None, description="the block's phase (normal, tangential), or a "
                                                           "loading program's phase number")
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


class Node(Record):
    """A contact node at one state (paper sign convention: u_N <= 0, r_N <= 0 compressive)."""

    id: int
    x: Number = Field(description="position along the contact line [length]")
    status: Literal["free", "zero", "stick", "slip"]
    sign: int = Field(description="slip direction S = sign(r_T) of a slip node, 0 otherwise")
    u_N: Number
    u_T: Number
    r_N: Number
    r_T: Number


class Certificate(Record):
    """What an analysis proved (or could not), and how (docs/proofs.md)."""

    status: str = Field(description="proven, not proven, ... (docs/proofs.md)")
    method: str
    rigorous: Optional[bool] = None
    interval: Optional[list[Number]] = Field(None, description="the interval of the claim (null end: infinity)")
    gap: Number = None
    seconds: Number = None
    detail: Optional[dict[str, Any]] = None
    cap: Number = Field(None, description="MCEIP-mu: the interval's upper end asked for")
    onset: Number = Field(None, description="MCEIP-mu: the proven smallest critical mu (null: none)")
    ill_conditioned: Optional[list[Number]] = None


class MceipSolution(Record):
    """One solution of an MCEIP (or one sufficient-condition mode) and the evidence for it.

    ``value`` is mu (MCEIP-mu, a [`CriticalMu`][app.io.result.CriticalMu]) or lambda^2 [1/s^2]
    (MCEIP-lambda^2, sufficient condition); ``x_Ts`` the mode on the slip nodes (sum 1, A to B);
    ``pattern`` slip/stick per slip node; the solver's evidence (residual, complementarity
    violation, iterations, ``found_by``: method and start) in :attr:`evidence`;
    ``certified``/``certificate`` when the analysis proved the solution; ``x`` the full
    kept-space vector of (10) when the run kept it in memory (never in results.json).
    """

    value: Number = Field(description="mu (MCEIP-mu) or lambda^2 [lambda2] (MCEIP-lambda^2)")
    x_Ts: FloatArray = Field(description="tangential rates of the slip nodes, A to B, summing to 1")
    pattern: Annotated[tuple[Literal["slip", "stick"], ...], AsList] = Field(description="per slip node, A to B")
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
    x: InMemory = Field(None, exclude=True, repr=False)

    @property
    def evidence(self) -> dict[str, Any]:
        """The evidence that it is a solution (:data:`EVIDENCE_KEYS` present in the record)."""
        data = self.to_dict()
        return {k: data[k] for k in EVIDENCE_KEYS if k in data}

    @property
    def all_slip(self) -> bool:
        """Every slip node of the state keeps slipping in this mode."""
        return all(p == "slip" for p in self.pattern)

    @property
    def n_stick(self) -> int:
        """Slip nodes of the state that stick in this mode."""
        return sum(p == "stick" for p in self.pattern)


class Status(Record):
    """Keys any analysis record may have instead of an answer."""

    failed: Optional[bool] = None
    reason: Optional[str] = None
    not_applicable: Optional[bool] = None

    @property
    def answered(self) -> bool:
        """The analysis gave an answer (it neither failed nor had nothing to compute)."""
        return not self.failed and not self.not_applicable


class NecessaryResult(Status):
    """Necessary condition (19) at mu: smallest eigenvalues of sym K*(mu) and sym M*(mu)."""

    satisfied: Optional[bool] = None
    mu: Number = None
    min_eig_K_sym: Number = None
    min_eig_M_sym: Number = None
    min_eig_K_sym_bounds: Optional[tuple[float, float]] = Field(
        None, description="where the value is not computed (the budget of the values on the contact DOFs spent): "
                          "bounds on it, its sign decided")
    min_eig_M_sym_bounds: Optional[tuple[float, float]] = None


class SufficientResult(Status):
    """Sufficient condition (17)-(18): admissible real eigenpairs lambda^2 > 0 with x_Ts >= 0."""

    satisfied: Optional[bool] = None
    mu: Number = None
    lambda2: FloatArray = Field(default_factory=lambda: float_array([]), description="[lambda2]")
    modes: Annotated[tuple[MceipSolution, ...], AsList] = ()


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


class MceipResult(Status):
    """The answer of one MCEIP analysis at one state (``mceip_mu``, ``mceip_lambda2`` or ``enumerate``).

    ``problem`` is ``mu`` or ``lambda2``; ``solutions`` sorted by value; ``result`` the one-line
    answer (found / none found / proven); ``search`` how the search was bounded (``complete`` is
    true only for a proof); ``mu`` the friction coefficient of MCEIP-lambda^2; ``failed``/``reason``
    when the solver failed; ``certified``/``certificate`` what is proven.
    """

    problem: Literal["mu", "lambda2"] = "lambda2"
    method: Optional[str] = None
    result: str = Field("", description="the one-line answer")
    mu: Number = Field(None, description="MCEIP-lambda^2: the friction coefficient")
    solutions: Annotated[tuple[MceipSolution, ...], AsList] = ()
    search: dict[str, Any] = Field(default_factory=dict,
                                   description="how the search was bounded ('complete': a proof)")
    certified: Optional[bool] = None
    certificate: Optional[Certificate] = None

    @model_validator(mode="after")
    def _critical_mu(self) -> "MceipResult":
        if self.problem == "mu":                      # mu prints with 4 decimals (CriticalMu)
            for s in self.solutions:
                if s.value is not None and type(s.value) is not CriticalMu:
                    s.__dict__["value"] = CriticalMu(s.value)
        return self

    @property
    def values(self) -> np.ndarray:
        """Every eigenvalue found, ascending."""
        return float_array([s.value for s in self.solutions])

    def min(self) -> float | None:
        """The smallest eigenvalue found (a [`CriticalMu`][app.io.result.CriticalMu] for MCEIP-mu), or None if none."""
        return min((s.value for s in self.solutions), default=None)

    def max(self) -> float | None:
        """The largest eigenvalue found, or None if none."""
        return max((s.value for s in self.solutions), default=None)


class MceipMuResult(MceipResult):
    """MCEIP-mu (21)-(23) at a state: its solutions are critical friction coefficients; ``onset``
    and ``complete`` the proof's two claims (docs/proofs.md); ``proof`` the pencil and proof log a
    run keeps for ``proofs/`` (never in results.json)."""

    problem: Literal["mu", "lambda2"] = "mu"
    onset: Optional[Onset] = None
    complete: Optional[Complete] = None
    proof: InMemory = Field(None, exclude=True, repr=False)


class EnumerationResult(MceipResult):
    """Exhaustive enumeration of the stick/slip patterns (small s): the first requested problem
    at the top level, every problem under ``problems``."""

    complete: Optional[bool] = None
    problems: Optional[dict[str, MceipResult]] = None


class Analyses(Record):
    """The analyses of a state (shared by the states of one classification)."""

    necessary: Optional[NecessaryResult] = None
    sufficient: Optional[SufficientResult] = None
    mceip_mu: Optional[MceipMuResult] = None
    mceip_lambda2: Optional[MceipResult] = None
    enumerate: Optional[EnumerationResult] = None


class StateResult(Record):
    """One equilibrium state: load, classification, contact nodes and analyses.

    ``analyses_shared_with`` is the index of the state whose analyses this state shares (same
    classification and signs), None when they were computed here. :attr:`necessary`,
    :attr:`mceip_mu`, ... are the analyses that gave an answer (None when not asked, failed or
    not applicable); :attr:`failed` the reasons of those that failed.
    """

    index: int
    load: Load
    classification: Classification
    nodes: Annotated[tuple[Node, ...], AsList]
    analyses: Analyses
    analyses_shared_with: Optional[int] = Field(description="state whose analyses these are; null: computed here")
    analysis_seconds: Number = None
    contact_solve: Optional[dict[str, Any]] = Field(None, description="how the contact increment was solved")

    def _answered(self, name: str):
        a = getattr(self.analyses, name)
        return a if a is not None and a.answered else None

    @property
    def necessary(self) -> NecessaryResult | None:
        """Necessary condition (19), when it gave an answer."""
        return self._answered("necessary")

    @property
    def sufficient(self) -> SufficientResult | None:
        """Sufficient condition (17)-(18), when it gave an answer."""
        return self._answered("sufficient")

    @property
    def mceip_mu(self) -> MceipMuResult | None:
        """MCEIP-mu (21)-(23), when it gave an answer."""
        return self._answered("mceip_mu")

    @property
    def mceip_lambda2(self) -> MceipResult | None:
        """MCEIP-lambda^2 (12)-(14), when it gave an answer."""
        return self._answered("mceip_lambda2")

    @property
    def enumerate(self) -> EnumerationResult | None:
        """The enumeration (24)-(26), when it gave an answer."""
        return self._answered("enumerate")

    @property
    def failed(self) -> dict[str, str]:
        """Analysis name -> the reason it failed."""
        out = {}
        for name in Analyses.model_fields:
            a = getattr(self.analyses, name)
            if a is not None and a.failed:
                out[name] = str(a.reason or "")
        return out

    def min_mu(self) -> CriticalMu | None:
        """Smallest critical friction coefficient found by MCEIP-mu at this state, None if none.

        ``print`` shows 4 decimals; the value itself is the full float (see [`CriticalMu`][app.io.result.CriticalMu]).
        """
        return None if self.mceip_mu is None else self.mceip_mu.min()

    def mu_values(self) -> np.ndarray:
        """Every MCEIP-mu value found at this state, ascending (empty if none or not asked)."""
        return float_array([]) if self.mceip_mu is None else self.mceip_mu.values

    def max_lambda2(self) -> float | None:
        """Largest admissible lambda^2 of the sufficient condition (17)-(18), None if none."""
        if self.sufficient is None or not len(self.sufficient.lambda2):
            return None
        return float(np.max(self.sufficient.lambda2))

    def counts(self) -> str:
        """``stick / slip / free`` node counts (and zero-reaction nodes if any), for messages."""
        c = self.classification
        return f"{c.stick} stick / {c.slip} slip / {c.free} free" + (f" / {c.zero} zero" if c.zero else "")


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


class TransientRun(Record):
    """One run of the dt study of a :class:`TransientRecord`."""

    dt: Number = Field(description="time step [time]")
    steps: int
    measured_rate: Number = Field(None, description="fitted growth rate of the mode's amplitude [1/time] "
                                                    "(null: it does not grow)")
    relative_error: Number = Field(None, description="|measured / predicted - 1| (null without a prediction)")
    energy_max_ratio: Number = Field(None, description="largest kinetic + elastic energy of the deviation / "
                                                       "its start")
    amplitude_max_ratio: Number = Field(None, description="largest |amplitude| / eps over the run")
    total_energy_change: Number = Field(None, description="the total mechanical energy at the end minus at the "
                                                          "start (kinetic + elastic + the held loads' work) "
                                                          "[force x length]: <= 0, friction and impacts dissipate")
    total_energy_rise: Number = Field(None, description="its largest rise above the start (0 up to rounding: the "
                                                        "scheme adds no energy)")
    final_status: dict[str, int] = Field(description="contact nodes free, stick, slip at the end of the run")
    status_changes: int = Field(description="steps at which some node changed its status")
    violation: Number = Field(description="largest violation of the contact laws over the steps (relative)")
    series: dict[str, list[Any]] = Field(description="t [time], the mode's amplitude [length] and the nodes' "
                                                     "statuses (0 free, 1 stick, 2 slip), subsampled")


class TransientRecord(Record):
    """The dynamics from one state (the scene's ``transient`` section, docs/validation.md)."""

    state: int
    mu: Number = Field(description="the friction coefficient of the dynamics")
    eps: Number = Field(description="the start's largest displacement [length]")
    predicted_rate: Number = Field(None, description="sqrt(lambda^2) of MCEIP-lambda^2's largest solution at mu "
                                                     "[1/time]; null: no divergence mode there")
    lambda2: Number = Field(None, description="that lambda^2 [1/time^2]")
    measured_rate: Number = Field(None, description="the finest run's fitted growth rate [1/time]")
    observed_order: Number = Field(None, description="of the rate's error, from the two finest runs")
    mode_singular: Number = Field(None, description="the mode's smallest singular value (relative): near 0 "
                                                    "when lambda^2 and the slip pattern fit")
    start: Optional[str] = None
    t_end: Number = Field(None, description="run length [time]")
    lowest_frequency: Number = Field(None, description="without a mode: the lowest circular frequency [1/time]")
    runs: Annotated[tuple[TransientRun, ...], AsList] = ()
    skipped: Optional[str] = Field(None, description="why this state was not run")


class StudyResult(Record):
    """A whole study (results.json, format 3, docs/outputs.md): the loading path's states and
    their analyses, with the run's evidence.

    Build it with [`app.run_study`][app.api.run_study], or from a saved ``results.json`` with
    [`load`][app.io.result.StudyResult.load]. Quantities are in the units of ``units``; no key
    name carries a unit. Records may hold keys beyond those listed here.
    """

    model_config = ConfigDict(extra="allow", arbitrary_types_allowed=True, title="results.json")

    format_version: Literal[FORMAT_VERSION] = FORMAT_VERSION
    scene: str
    units: Units
    system: str = Field(description="the system, in words")
    mu: Number = Field(description="the scene's friction coefficient")
    analyses_requested: Annotated[tuple[str, ...], AsList]
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
    transient: Optional[Annotated[tuple[TransientRecord, ...], AsList]] = Field(
        None, description="the dynamics from the scene's transient states (docs/validation.md)")
    non_finite: Optional[NonFinite] = Field(None, exclude=True, description=(
        "the numbers written as null because they are not finite (written by to_json, not kept)"))
    states: Annotated[tuple[StateResult, ...], AsList]

    @classmethod
    def from_dict(cls, results: dict) -> "StudyResult":
        """From a results dictionary (a study's, or a results.json document of any format version
        read by :func:`app.io.document.from_document`, which brings it to this format)."""
        data = dict(results)
        data.pop("format_version", None)
        data.pop("non_finite", None)
        return cls.model_validate(data)

    @classmethod
    def from_json(cls, doc: dict) -> "StudyResult":
        """From a results.json document (JSON data, any format version): :meth:`to_json` read back."""
        return cls.from_dict(from_document(doc))

    @classmethod
    def load(cls, path: str | pathlib.Path) -> "StudyResult":
        """Read a ``results.json`` (or the results folder holding it), of any format version."""
        p = pathlib.Path(path)
        if p.is_dir():
            p = p / "results.json"
        return cls.from_json(json.loads(p.read_text(encoding="utf-8")))

    def __len__(self) -> int:
        return len(self.states)

    def __iter__(self) -> Iterator[StateResult]:      # type: ignore[override]
        return iter(self.states)

    @property
    def final(self) -> StateResult:
        """The last equilibrium state of the path."""
        return self.states[-1]

    def state(self, index: int) -> StateResult:
        """The state with this ``index`` (state indices follow the loading path from 0)."""
        for s in self.states:
            if s.index == index:
                return s
        raise KeyError(f"no state {index} (indices {self.states[0].index} to {self.states[-1].index})"
                       if self.states else f"no state {index}: the study has no states")

    def first_instability(self) -> StateResult | None:
        """The first state along the path at which MCEIP-mu has a solution (a critical mu), or None.

        It is the first state where divergence is possible for some friction coefficient; whether
        it is possible for the scene's mu is the question of MCEIP-lambda^2 and (17)-(18).
        """
        return next((s for s in self.states if s.mceip_mu is not None and s.mceip_mu.solutions), None)

    def min_mu_along_path(self) -> np.ndarray:
        """Smallest MCEIP-mu value at every state (NaN where none was found)."""
        return float_array([math.nan if (m := s.min_mu()) is None else m for s in self.states])

    @property
    def complete(self) -> bool:
        """No state failed (the CLI exits with status 3 otherwise)."""
        return not self.failures

    def to_json(self) -> dict:
        """The results.json document, exactly as the CLI writes it (`to_document`): JSON data
        (finite numbers, strings, lists, dicts); what is kept in memory only is left out, and
        non-finite numbers are written as ``null`` and listed in the ``non_finite`` block."""
        return to_document(self.to_dict())


def json_schema() -> dict:
    """The JSON Schema of results.json (docs/results-schema.json), from the models above."""
    schema = StudyResult.model_json_schema(mode="validation")
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **schema}


def _no_constant(word: str):
    raise ValueError(f"{word} is not a JSON number (results.json writes a non-finite number as null)")


def validate(text: str) -> StudyResult:
    """Parse a results.json text with the models, strictly (a number must be a JSON number: a
    string "inf" and the literals NaN and Infinity, which JSON does not have, are refused);
    raises pydantic.ValidationError or ValueError."""
    try:
        json.loads(text, parse_constant=_no_constant)
    except RecursionError:
        raise ValueError("nested too deeply to be a results.json") from None
    return StudyResult.model_validate_json(text, strict=True)
