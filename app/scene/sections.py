"""The sections of a scene beside its system: solver settings (with the resource limits of
:class:`app.systems.schema.Limits`), the sweep of a batch of cases, the outputs for people and
the mesh-refinement study.

:class:`app.scene.schema.Scene` assembles them (and re-exports them); each is a frozen pydantic model
whose validation errors become one line (app/common/validation.py).
"""
from __future__ import annotations

import re
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import Field, field_validator, model_validator

from app.common.validation import PathError, Strict, one_line, show_value
from app.systems.schema import Limits, NonNegFloat, PosFloat


class McpSettings(Strict):
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
    # Proofs for the condensed MCEIP-mu (app/analyses/mceip_mu, docs/proofs.md): the onset and every
    # critical mu up to the cap; the cap is mu_cap, or mu_cap_factor x the scene's mu.
    certify: bool = True
    mu_cap: Optional[PosFloat] = None
    mu_cap_factor: PosFloat = 10.0
    # The budgets of the proofs count work (proof-tree nodes), never seconds, so that a scene gives
    # the same statuses on any machine, under any load and on any number of ranks. The *_seconds keys
    # are a wall-clock safety stop only, off by default (null); a proof one of them ends says
    # "stopped by the time limit", never "not proven within budget".
    certify_seconds: Optional[PosFloat] = Field(
        None, description="safety stop per state for the MCEIP-mu proof (linear and quadratic), wall clock [s]; "
                          "null: none. Not a budget (the budgets count nodes): a proof it ends is reported as "
                          "'stopped by the time limit'")
    # floating-point enumeration of every support gives the proof's candidates up to here, the search above
    certify_enumerate_max: Annotated[int, Field(ge=0, le=20)] = 12
    certify_all_max: Annotated[int, Field(ge=0, le=1000)] = Field(
        22, description="the complete list of critical mu below the cap is proven up to this many slip nodes "
                        "(the onset at any size)")
    certify_onset_nodes: Annotated[int, Field(ge=1, le=10_000_000)] = Field(
        20000, description="budget per state for the onset proof, in proof-tree nodes (an unfinished proof says "
                          "what it proved: no critical mu below a bound)")
    certify_all_nodes: Annotated[int, Field(ge=0, le=10_000_000)] = Field(
        5000, description="budget per state for the complete list once the onset is proven, in proof-tree "
                          "nodes (deterministic: the same answer on any machine)")
    certify_all_seconds: Optional[PosFloat] = Field(
        None, description="safety stop per state for the complete list, wall clock [s]; null: none "
                          "(certify_all_nodes is the budget)")
    certify_quadratic_nodes: Annotated[int, Field(ge=1, le=400_000)] = Field(
        20000, description="budget per state for the quadratic MCEIP-mu of a curved obstacle above 8 slip nodes "
                           "(the branch and bound), in proof-tree nodes; up to 8 slip nodes every support is "
                           "decided exactly (at most 255)")
    lambda2_exact_max_dofs: Annotated[int, Field(ge=0, le=20_000)] = Field(
        1500, description="MCEIP-lambda^2's exact reduction to the slip nodes (the proof of no solution) "
                          "from the dense (K, M) eigen-decomposition up to this many DOFs, from a sparse "
                          "factorisation of K + t M per t above; the SNES VI search runs where the proof fails")
    # condensed MCEIP-mu search: above this many slip nodes the "x zero on one node" starts (nearly
    # uniform there) are left out, half the Newton runs (app/analyses/mceip_mu/candidates.py)
    search_zero_one_max: Annotated[int, Field(ge=0, le=100_000)] = 40
    lambda2_full_search_max_dofs: Annotated[int, Field(ge=0, le=100_000_000)] = Field(
        200_000, description="MCEIP-lambda^2 where its proof on the exact reduction fails: up to this many DOFs "
                             "the SNES VI search on the full system; above, the search on the exact reduction in "
                             "the intervals of lambda^2 the proof could not certify (the full system's search "
                             "factorises it at every Newton step: hours per state at 10^6 DOFs)")
    # large condensed problems (100k-DOF studies): above search_full_max slip nodes the search
    # runs a reduced start set (uniform x and x on search_one_node spread unknowns with every t0, the
    # all-slip eigenvectors, the previous classification's solutions within a chain of warm_chain
    # classifications along the path) and the onset proof gets certify_onset_nodes_large instead of
    # certify_onset_nodes; an unfinished proof says what it proved
    search_full_max: Annotated[int, Field(ge=0, le=100_000)] = Field(
        40, description="condensed MCEIP-mu: above this many slip nodes, the reduced search and "
                        "certify_onset_nodes_large")
    search_one_node: Annotated[int, Field(ge=2, le=100_000)] = Field(
        4, description="reduced search: number of evenly spaced one-node starts")
    warm_chain: Annotated[int, Field(ge=1, le=100_000)] = Field(
        8, description="classifications per warm-started chain along the path (one rank per chain)")
    prove_first: bool = Field(
        True, description="above search_full_max slip nodes, first try the search-free proof that no critical mu "
                          "lies in [0, cap] (sign argument, intervals halved); when it succeeds the search is "
                          "skipped, so values above the cap are not listed")
    certify_onset_nodes_large: Annotated[int, Field(ge=0, le=10_000_000)] = Field(
        500, description="budget per state for the onset proof above search_full_max slip nodes, in proof-tree "
                         "nodes (0: no branch and bound, only the verified candidates and the sign argument on "
                         "every support)")
    certify_seconds_large: Optional[NonNegFloat] = Field(
        None, description="safety stop per state for the proof above search_full_max slip nodes, wall clock [s] "
                          "(instead of certify_seconds); null: none")


class EigSettings(Strict):
    """SLEPc settings for the necessary and sufficient conditions."""

    dense_limit: Annotated[int, Field(ge=1, le=10_000)] = 500
    nev: Annotated[int, Field(ge=1, le=1000)] = 30
    tol: Annotated[float, Field(gt=0, lt=1)] = 1e-10
    max_it: Annotated[int, Field(ge=1, le=1_000_000)] = 1000
    necessary_contact_min_dofs: Annotated[int, Field(ge=0, le=10**9)] = Field(
        5000, description="from this many DOFs on, the values of the necessary condition (19) come from the "
                          "contact DOFs (the secular equation of the Schur complement, a few dozen factorisations "
                          "shared by the whole path; docs/method.md section 2) instead of two full-size "
                          "factorisations per classification")
    necessary_value_work: Annotated[float, Field(gt=0, le=1e15)] = Field(
        1.0e7, description="budget of the values of (19) on the contact DOFs, per matrix (K, M) and path, in "
                           "DOF-factorisations (the exact Schur complements it computes times the system's DOFs: "
                           "100 at 100k DOFs, where the path needs 70, 10 at 10^6, fewer than one interpolated piece); once spent, a value is reported as bounds "
                           "(min_eig_K_sym_bounds) with its sign decided. Work, not time: the same answers on any "
                           "machine")


class Settings(Strict):
    """Solver settings: the tolerance of the node classification, the MCP search and SLEPc settings,
    the enumeration's size limit and problems, the MCEIP-mu method and the resource limits checked
    before any work."""

    classify_rtol: Annotated[float, Field(gt=0, lt=1)] = 1e-8
    mcp: McpSettings = McpSettings()
    eig: EigSettings = EigSettings()
    enumerate_max_slip: Annotated[int, Field(ge=1, le=24)] = 14
    enumerate_problems: Annotated[list[Literal["mu", "lambda2"]], Field(max_length=2)] = ["mu", "lambda2"]
    mceip_mu_method: Literal["condensed", "full"] = "condensed"
    limits: Limits = Field(Limits(), description="resource limits checked before any work (docs/safety.md)")


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
        raise PathError(key, spec, f"unknown range key '{extra[0]}': {allowed}")
    if "start" not in spec or "stop" not in spec or ("num" in spec) == ("step" in spec):
        raise PathError(key, spec, allowed)
    start, stop = spec["start"], spec["stop"]
    if not (_is_number(start) and _is_number(stop) and all(abs(v) <= 1e300 for v in (start, stop))):
        raise PathError(key, spec, f"start and stop must be finite numbers: {allowed}")
    if "num" in spec:
        num = spec["num"]
        if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= _SWEEP_MAX_VALUES:
            raise PathError(key, spec, f"num must be an integer from 1 to {_SWEEP_MAX_VALUES}")
        if num == 1 and start != stop:
            raise PathError(key, spec, "num = 1 needs start = stop (a single value)")
        raw = [float(start) + (float(stop) - float(start)) * i / max(num - 1, 1) for i in range(num)]
        ints = isinstance(start, int) and isinstance(stop, int)
    else:
        step = spec["step"]
        if not _is_number(step) or not 0 < step <= 1e300:
            raise PathError(key, spec, "step must be a positive number (it goes from start towards stop)")
        count = abs(float(stop) - float(start)) / float(step)
        if not count < _SWEEP_MAX_VALUES:
            raise PathError(key, spec, f"more than {_SWEEP_MAX_VALUES} values")
        count = int(count + 1e-9) + 1
        sign = 1 if stop >= start else -1
        raw = [float(start) + sign * float(step) * i for i in range(count)]
        ints = all(isinstance(v, int) for v in (start, stop, step))
    # round away the binary noise of the arithmetic (0.30000000000000004 -> 0.3): stable case names
    out = [float(f"{v:.12g}") for v in raw]
    return [int(v) for v in out] if ints and all(v == int(v) for v in out) else out


class Sweep(Strict):
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
                raise PathError(one_line(str(key)), values, "a swept key must be a dotted path of scene keys, "
                                 "e.g. mu or system.length")
            if key.split(".")[0] in ("name", "sweep"):
                raise PathError(key, values, "cannot be swept (the case names and the output folders are "
                                 "made from the swept values)")
            if isinstance(values, dict):
                values = _sweep_range(key, values)
            if not isinstance(values, (list, tuple)) or not values:
                raise PathError(key, values, "allowed: a non-empty list of values [v1, v2, ...] or a range "
                                 "{start, stop, num} or {start, stop, step}")
            if len(values) > _SWEEP_MAX_VALUES:
                raise PathError(key, values, f"more than {_SWEEP_MAX_VALUES} values")
            for x in values:
                if not (x is None or isinstance(x, (bool, int, float, str)) or (
                        isinstance(x, (list, tuple)) and all(isinstance(y, (bool, int, float, str)) for y in x))):
                    raise PathError(key, values, f"the value {show_value(x)} is not allowed: values are numbers, strings, "
                                     "booleans or lists of them (sweep the keys inside a section, e.g. system.nx)")
            seen: set = set()
            dup = sorted({n for n in map(repr, values) if n in seen or seen.add(n)})
            if dup:
                raise PathError(key, values, f"each value may be listed once; listed twice: {', '.join(dup)}")
            out[key] = list(values)
        for a in out:
            for b in out:
                if b.startswith(a + "."):
                    raise PathError(b, out[b], f"inside the swept key '{a}': sweep one or the other")
        return out

    @model_validator(mode="after")
    def _sizes(self) -> "Sweep":
        sizes = {k: len(v) for k, v in self.parameters.items()}
        if self.mode == "zip" and len(set(sizes.values())) > 1:
            raise PathError("parameters", sizes, "mode 'zip' needs the same number of values for every key "
                             "(numbers of values shown)")
        total = 1
        for n in sizes.values():
            total = n if self.mode == "zip" else total * n
        if total > _SWEEP_MAX_VALUES:
            raise PathError("parameters", sizes, f"{total} cases (numbers of values shown): "
                             f"at most {_SWEEP_MAX_VALUES} per sweep")
        return self


STATE_WORDS = ("final", "first_mceip_mu", "all_distinct")
_STATE_ALLOWED = ("allowed: a state index (an integer >= 0), 'final', 'first_mceip_mu', 'all_distinct', or node "
                  "counts selecting the first state that has them, e.g. {stick: 2, slip: 15, free: 4}")


class StateCounts(Strict):
    """The first state whose node counts equal every count given, e.g. {stick: 2, slip: 15, free: 4}."""

    stick: Optional[Annotated[int, Field(ge=0)]] = None
    slip: Optional[Annotated[int, Field(ge=0)]] = None
    free: Optional[Annotated[int, Field(ge=0)]] = None
    zero: Optional[Annotated[int, Field(ge=0)]] = None


class Screenshots(Strict):
    """Off-screen pyvista pictures of the body (app/plot/screenshots.py)."""

    resolution: tuple[Annotated[int, Field(ge=100, le=8192)], Annotated[int, Field(ge=100, le=8192)]] = (1200, 800)
    field: Literal["displacement", "von_mises"] = "von_mises"
    modes: bool = True               # also draw every divergence mode found at the pictured states
    scale: PosFloat = 1.0            # magnification of the state displacements (modes are scaled to fit)
    animate: bool = False            # also an animated GIF of each mode drawn, growing as exp(lambda t)


class Outputs(Strict):
    """Files and pictures for people (app/io/, app/plot/); all off unless asked for."""

    paraview: bool = False           # XDMF time series of the states, VTU of the modes (systems with a mesh)
    plots: bool = False              # matplotlib PNG + SVG
    report: bool = False             # report.md
    states: list[Union[Annotated[int, Field(ge=0, strict=True)], Literal["final", "first_mceip_mu", "all_distinct"],
                       StateCounts]] = ["final"]   # the states pictured (screenshots, reactions along AB)
    screenshots: Optional[Screenshots] = None     # true: the defaults (systems with a mesh)

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
                raise PathError(str(i), s, _STATE_ALLOWED)
            if isinstance(s, int) and s < 0:
                raise PathError(str(i), s, _STATE_ALLOWED)
            if isinstance(s, dict):
                for key, n in s.items():
                    if key not in StateCounts.model_fields:
                        raise PathError(f"{i}.{one_line(str(key))}", s, "unknown node status: allowed keys are "
                                         "stick, slip, free, zero (node counts)")
                    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
                        raise PathError(f"{i}.{key}", n, "allowed: a node count (an integer >= 0)")
                if not s:
                    raise PathError(str(i), s, _STATE_ALLOWED)
        return v

    @property
    def fields(self) -> bool:
        """Displacement/stress/mode fields are needed (ParaView files or screenshots)."""
        return self.paraview or self.screenshots is not None

    @property
    def any(self) -> bool:
        """Something is asked for: fields (ParaView files or screenshots), plots or the report."""
        return self.fields or self.plots or self.report


def annotation_types(tp: Any) -> list:
    """The leaf types of an annotation (the members of unions and optionals)."""
    import typing
    args = typing.get_args(tp)
    return [tp] if not args else [t for a in args for t in annotation_types(a)]


class Transient(Strict):
    """Nonsmooth dynamics from chosen states (app/analyses/transient/, docs/validation.md): does the
    divergence MCEIP-lambda^2 predicts happen? Each state, its applied loads held, is started on
    its divergence mode at the friction coefficient ``mu`` (default: MCEIP-lambda^2's) and
    integrated with the contact laws solved exactly at every step; with ``mu`` other than the
    scene's, the state is held on that mu's Coulomb cone (its slip nodes' ``r_T = S mu |r_N|``)."""

    states: list[Union[Annotated[int, Field(ge=0, strict=True)], Literal["final", "first_mceip_mu"]]] = Field(
        ["final"], min_length=1, max_length=10, description="the states started from (as outputs.states)")
    mu: Optional[NonNegFloat] = Field(None, description="friction coefficient of the dynamics (default: "
                                      "mceip_lambda2_mu, else mu)")
    eps: PosFloat = Field(1e-7, description="the start's largest displacement [length]: small enough that "
                          "the statuses hold while the mode grows 'growth' times")
    growth: Annotated[float, Field(gt=1.0, le=1e8)] = Field(1000.0, description="how many times the mode grows "
                                                           "over a run (its length: ln(growth) / lambda)")
    steps: Annotated[list[Annotated[float, Field(gt=0.0, le=1.0)]], Field(min_length=1, max_length=6)] = Field(
        [0.04, 0.02, 0.01], description="time steps, as fractions of 1 / lambda (the dt study, coarse to fine)")
    t_end: Optional[PosFloat] = Field(None, description="run length [time] at a state with no divergence mode "
                                      "(default: that of the other states, else 20 periods of the lowest mode)")
    mode_mu: Optional[NonNegFloat] = Field(None, description="at a state with no divergence mode at mu: start "
                                           "from its mode at this friction coefficient (the same classification "
                                           "above its onset), at rest, for as long as that mode takes to grow "
                                           "'growth' times (default: a static push of the slip nodes)")


class Refinement(Strict):
    """A mesh-refinement study (app/study/refinement.py): the scene at every mesh level, every degree
    and every plane model. The block's levels are ``levels`` (nx cells along AB, ny = nx * height /
    length); a Gmsh body's are ``size_factors`` (its .geo's characteristic lengths times each factor,
    ``system.mesh_size_factor``)."""

    levels: Optional[Annotated[list[Annotated[int, Field(ge=1, le=4096)]], Field(min_length=2, max_length=50)]] = None
    size_factors: Optional[Annotated[list[PosFloat], Field(min_length=2, max_length=50)]] = None
    degrees: Annotated[list[Literal[1, 2]], Field(min_length=1, max_length=2)] = [1]
    planes: Annotated[list[Literal["stress", "strain"]], Field(min_length=1, max_length=2)] = ["stress"]
    mu_fixed: Optional[NonNegFloat] = None     # mu of the sufficient condition at the final state
    resultant_at: PosFloat = 1.0               # |CD u_x| [mm] of the state whose resultants are compared
    first_solution: Literal["scan", "none"] = "scan"    # none: skip the search for the first solution
    max_contact_nodes: Optional[Annotated[int, Field(ge=2)]] = None   # skip levels with more (degree * nx + 1)

    @field_validator("levels", "size_factors", "degrees", "planes")
    @classmethod
    def _distinct(cls, v: list | None, info) -> list | None:
        if v is None:
            return v
        if len(set(v)) != len(v):
            raise ValueError("each value may be listed once")
        if info.field_name == "size_factors":       # coarse to fine
            return sorted(v, reverse=True)
        return sorted(v) if v and isinstance(v[0], int) else v

    def steps(self) -> list:
        """The mesh levels in order, coarse to fine (nx, or size factors)."""
        return list(self.levels if self.levels is not None else self.size_factors or [])
