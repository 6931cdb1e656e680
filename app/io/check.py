"""``python -m app check RESULTS``: every MCEIP-mu claim of results.json re-derived from the stored pencils.

A claim is what results.json calls proven at a state (paper eqs. (21)-(23), docs/proofs.md):

* the **onset**: no critical mu in ``[0, cap]`` (``onset.value`` null), or the smallest critical mu
  lies in ``onset.enclosure``, with ``onset.value`` inside it;
* the **complete list**: every critical mu in ``complete.interval`` is one of the solutions marked
  ``certified``, with the stated count;
* each **certified solution**: a critical mu inside the stated ``enclosure``, with the stated support;
* the **lower bound** ``certificate.detail.lower_bound``: no critical mu below it;
* ``certified: true`` claims the onset and the complete list.

For each state making a claim, the pencil of its classification (``proofs/state_<k>.npz`` of the
state ``k`` whose analyses it shares) is read with its headers checked before anything is
allocated (:mod:`app.io.untrusted`), its structure is derived from the pencil and the state's
classification (size ``s`` = slip nodes + 3 per zero-reaction node; the zero-reaction pairs at
their fixed places, verified to be exactly opposite columns), never taken from the log, and the
proof is re-verified by the independent checker with those pairs. What the checker proves is then
compared with each claim: the log's ``cap`` must cover the claimed interval, every claimed value must
lie in its proven enclosure. A state without slip nodes needs no pencil: its claim is that there is
no critical mu, and its classification says so. A missing or unreadable proof file fails every claim
that needs it. What ``check`` trusts is said in docs/proofs.md.
"""
from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass, field

import numpy as np

from app.io.claims import (
    MalformedResults,
    SolutionClaim,
    StateClaims,
    json_number,
    json_object,
    read_results,
    state_claims,
)
from app.io.untrusted import UntrustedFile, inside, parse_json, read_npz

FOLDER = "proofs"


# --- what a stored proof proves ----------------------------------------------------------------------


@dataclass
class Proven:
    """What the checker re-derived from one stored pencil (every number rigorous).

    ``free_below``: no critical mu in ``[0, free_below]``; ``onset``: the proven enclosure of the
    smallest critical mu (``onset_known`` when it is proven; None with it: none up to ``cap``);
    ``complete``: ``solutions`` (support or None, low, high) are every critical mu in ``[0, cap]``."""

    cap: float = 0.0
    free_below: float = 0.0
    onset_known: bool = False
    onset: tuple[float, float] | None = None
    complete: bool = False
    solutions: list[tuple[tuple[int, ...] | None, float, float]] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)


def _linear(A0: np.ndarray, A1: np.ndarray, raw: object, pairs, s: int) -> Proven:
    """Re-verify a ``mceip-mu-proof`` log with the checker, the derived ``pairs`` replacing the log's."""
    from app.analyses.mceip_mu.kernel.checker import check_log
    from app.analyses.mceip_mu.kernel.prooflog import ProofLog
    log = ProofLog.from_json(json_object(raw, "proof log"))
    if log.s != s:
        return Proven(errors=[f"the log is for s = {log.s}, the pencil has s = {s}"])
    if not (math.isfinite(log.cap) and log.cap >= 0 and abs(log.scale_exp) <= 2000):
        return Proven(errors=[f"the log's cap {log.cap!r} or scale {log.scale_exp!r} is out of range"])
    if {tuple(sorted(p)) for p in log.pairs} != {tuple(sorted(p)) for p in pairs}:
        return Proven(errors=[f"the log's pairs {log.pairs[:3]} are not the classification's {pairs[:3]}"])
    log.pairs = list(pairs)
    rep = check_log(A0, A1, log)
    out = Proven(cap=log.cap, errors=list(rep.errors[:3]))
    out.free_below = max(rep.lower_bound, 0.0)
    out.onset_known = rep.onset_ok
    if rep.onset_ok:
        out.onset = rep.onset
        if rep.onset is None:
            out.free_below = max(out.free_below, log.cap)
    out.complete = rep.all_ok
    out.solutions = [(tuple(int(i) for i in U), float(lo), float(hi)) for U, lo, hi in rep.solutions]
    if rep.onset is not None and not any(lo <= rep.onset[1] and rep.onset[0] <= hi for _, lo, hi in out.solutions):
        out.solutions.append((None, rep.onset[0], rep.onset[1]))
    if rep.all_ok and not rep.solutions:
        out.free_below = max(out.free_below, log.cap)
    return out


def _quadratic(A0, A1, A2, raw: object, pairs, cap: float) -> Proven:
    """Re-prove a quadratic pencil (per support, exactly) or
    re-verify its branch-and-bound log, with the derived ``pairs``. The log's own ``cap`` and
    ``max_s`` are never used by the per-support proof: it runs on the claimed cap, and only up to the
    run's own :data:`~app.analyses.mceip_mu.quadratic.problem.PROOF_MAX_S` slip nodes."""
    from app.analyses.mceip_mu.quadratic.problem import PROOF_MAX_S, QUADRATIC_BB_FORMAT, QUADRATIC_FORMAT
    from app.analyses.mceip_mu.quadratic.proof import pairs_hold
    s = A0.shape[0]
    logged = raw.get("pairs", []) if isinstance(raw, dict) else None
    if not isinstance(logged, list) or not all(isinstance(p, list) and len(p) == 2 for p in logged) \
            or {tuple(sorted(map(int, p))) for p in logged} != {tuple(sorted(p)) for p in pairs}:
        return Proven(errors=[f"the log's pairs {str(logged)[:40]} are not the classification's {pairs[:3]}"])
    if not pairs_hold(A0, A1, A2, pairs):
        return Proven(errors=["the zero-reaction pairs are not exactly opposite columns of the pencil"])
    fmt = raw.get("format") if isinstance(raw, dict) else None
    if fmt == QUADRATIC_FORMAT:
        if s > PROOF_MAX_S:
            return Proven(errors=[f"s = {s}: the exact per-support proof is re-run up to {PROOF_MAX_S} slip nodes"])
        from app.analyses.mceip_mu.quadratic.proof import prove_quadratic
        proof = prove_quadratic(A0, A1, A2, cap, max_s=PROOF_MAX_S, pairs=pairs)
        out = Proven(cap=cap)
        if proof is None or not proof.proven:
            out.errors.append("the exact proof does not decide every support")
            return out
        out.complete = out.onset_known = True
        out.solutions = [(tuple(p.support), *map(float, p.enclosure)) for p in proof.solutions]
        on = proof.onset
        out.onset = None if on is None else tuple(map(float, on.enclosure))
        out.free_below = cap if on is None else float(on.enclosure[0])
        return out
    if fmt == QUADRATIC_BB_FORMAT:
        from app.analyses.mceip_mu.quadratic.check import check_log
        log = dict(raw)
        log["pairs"] = [list(p) for p in pairs]
        log_cap = json_number(log.get("cap"), "proof log cap")
        if not isinstance(log.get("nodes"), list):
            raise MalformedResults("proof log: no node list")
        rep = check_log(A0, A1, A2, log)
        out = Proven(cap=log_cap, errors=list(rep.errors[:3]))
        if rep.errors:
            return out
        out.complete = rep.complete
        out.solutions = [(tuple(p.support), *map(float, p.enclosure)) for p in rep.solutions]
        out.onset_known = rep.onset_proven
        on = rep.onset
        out.onset = None if on is None or not rep.onset_proven else tuple(map(float, on.enclosure))
        # every solution below the lowest open node is listed: none below the first of them
        first = min((lo for _, lo, _ in out.solutions), default=math.inf)
        out.free_below = min(rep.open_from, first, log_cap)
        return out
    return Proven(errors=[f"proof format {fmt!r}, expected {QUADRATIC_FORMAT!r} or {QUADRATIC_BB_FORMAT!r}"])


# --- comparing -----------------------------------------------------------------------------------------


@dataclass
class StateCheck:
    """The verdict on one state's claims: ``verified`` lists what was re-derived, ``failed`` what was not."""

    state: int
    s: int
    proof_state: int
    verified: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """Every claim of the state re-derived from its stored pencil."""
        return not self.failed


def _within(v: float, lo: float, hi: float) -> bool:
    return lo <= v <= hi


def compare(c: StateClaims, p: Proven) -> StateCheck:
    """Each claim of ``c`` against what the checker proved (``p``)."""
    out = StateCheck(c.state, c.s, c.proof_state)
    why = f" ({'; '.join(p.errors)})" if p.errors else ""
    if c.onset is not None:
        value, enc, cap = c.onset
        if value is None:
            ok = p.free_below >= cap
            (out.verified if ok else out.failed).append(
                f"no critical mu in [0, {cap:.6g}]" + ("" if ok else f": proven only up to {p.free_below:.6g}{why}"))
        else:
            ok = p.onset_known and p.onset is not None and enc is not None and enc[0] <= p.onset[0] \
                and p.onset[1] <= enc[1] and _within(value, *p.onset)
            got = f"proven enclosure [{p.onset[0]:.12g}, {p.onset[1]:.12g}]" if p.onset_known and p.onset \
                else "no proven onset"
            (out.verified if ok else out.failed).append(f"onset mu = {value:.10g}" + ("" if ok else f": {got}{why}"))
    if c.complete is not None:
        end, count = c.complete
        problem = _list_problem(c, p, end, count)
        (out.verified if problem is None else out.failed).append(
            f"complete list on [0, {end:.6g}]" + ("" if problem is None else f": {problem}{why}"))
    for sol in c.solutions:
        if c.complete is not None and sol.value <= c.complete[0]:
            continue                          # checked with the list
        ok = any(_matches(sol, sp) for sp in p.solutions)
        (out.verified if ok else out.failed).append(
            f"critical mu = {sol.value:.10g}" + ("" if ok else f": not inside a proven enclosure{why}"))
    if c.lower_bound > 0:
        ok = p.free_below >= c.lower_bound
        (out.verified if ok else out.failed).append(
            f"no critical mu below {c.lower_bound:.6g}" + ("" if ok else f": proven only up to {p.free_below:.6g}{why}"))
    return out


def _matches(sol: SolutionClaim, proven: tuple) -> bool:
    """A claimed solution is a proven one: its value inside the proven enclosure, its stated enclosure
    holding it, its support the proven one (when both are known)."""
    support, lo, hi = proven
    if not _within(sol.value, lo, hi):
        return False
    if sol.enclosure is not None and not (sol.enclosure[0] <= lo and hi <= sol.enclosure[1]):
        return False
    return sol.support is None or support is None or tuple(sol.support) == tuple(support)


def _list_problem(c: StateClaims, p: Proven, end: float, count: int | None) -> str | None:
    """Why the complete-list claim on ``[0, end]`` is not proven by ``p`` (None: it is)."""
    if not p.complete:
        return "the proof does not establish a complete list"
    if p.cap < end:
        return f"the proof covers [0, {p.cap:.6g}] only"
    inside_ = [sp for sp in p.solutions if sp[2] <= end]
    if any(sp[1] <= end < sp[2] for sp in p.solutions):
        return f"a proven value straddles the claimed end {end:.6g}"
    claimed = sorted((s for s in c.solutions if s.value <= end), key=lambda s: s.value)
    if count is not None and count != len(claimed):
        return f"count {count} but {len(claimed)} certified solutions listed"
    if len(claimed) != len(inside_):
        return f"{len(claimed)} values claimed, {len(inside_)} proven"
    for sol, sp in zip(claimed, sorted(inside_, key=lambda t: t[1])):
        if not _matches(sol, sp):
            return f"mu = {sol.value:.10g} is not the proven value in [{sp[1]:.12g}, {sp[2]:.12g}]"
    return None


# --- the folder ------------------------------------------------------------------------------------


@dataclass
class FolderCheck:
    """Every state's verdict (only states claiming something proven), and the proof files read."""

    states: list[StateCheck]
    proof_files: int

    @property
    def ok(self) -> bool:
        """Every claim of the folder re-derived."""
        return all(s.ok for s in self.states)

    @property
    def claims(self) -> int:
        """The number of claims examined."""
        return sum(len(s.verified) + len(s.failed) for s in self.states)

    @property
    def failed(self) -> int:
        """The number of claims not re-derived."""
        return sum(len(s.failed) for s in self.states)

    def lines(self) -> list[str]:
        """One line per run of consecutive states with the same pencil and the same verdicts."""
        out, group = [], []
        for c in self.states + [None]:
            if group and (c is None or _key(c) != _key(group[0])):
                g = group[0]
                states = f"state {g.state}" if len(group) == 1 else f"states {g.state}-{group[-1].state}"
                pencil = f", {FOLDER}/state_{g.proof_state}.npz" if g.s else ""
                out.append(f"{states} (s = {g.s}{pencil}): " + "; ".join(
                    [f"{v}: re-verified" for v in g.verified] + [f"{v}: NOT VERIFIED" for v in g.failed]))
                group = []
            if c is not None:
                group.append(c)
        return out


def _key(c: StateCheck) -> tuple:
    """What a line of :meth:`FolderCheck.lines` groups states by."""
    return (c.proof_state if c.s else None, c.verified, c.failed)


def _max_side() -> int:
    """The largest pencil side read: 3 columns per contact node at the app's default limit (never a
    value from the folder)."""
    from app.systems.schema import Limits
    return 3 * Limits().max_contact_nodes


def check_folder(folder: pathlib.Path) -> FolderCheck:
    """Re-derive every MCEIP-mu claim of the results folder ``folder`` (module docstring)."""
    every = state_claims(read_results(folder))
    claims = [c for c in every if c.any]
    by_index = {c.state: c for c in every}
    max_side = _max_side()
    cache: dict[int, Proven | str] = {}
    checks = []
    for c in claims:
        if c.statuses and (c.statuses.count("slip"), c.statuses.count("zero")) != (c.slip, c.zero):
            out = StateCheck(c.state, c.s, c.proof_state)
            out.failed.append(f"its classification counts {c.slip} slip and {c.zero} zero-reaction nodes, its "
                              f"nodes {c.statuses.count('slip')} and {c.statuses.count('zero')}")
            checks.append(out)
            continue
        if c.s == 0:
            checks.append(_no_slip(c))
            continue
        first = by_index.get(c.proof_state)
        if first is None or first.statuses != c.statuses or (first.slip, first.zero) != (c.slip, c.zero):
            out = StateCheck(c.state, c.s, c.proof_state)
            out.failed.append(f"shares the analyses of state {c.proof_state}, whose classification differs")
            checks.append(out)
            continue
        if c.proof_state not in cache:
            cache[c.proof_state] = _prove(folder, c, max_side)
        got = cache[c.proof_state]
        if isinstance(got, str):
            out = StateCheck(c.state, c.s, c.proof_state)
            out.failed.append(got)
            checks.append(out)
        else:
            checks.append(compare(c, got))
    return FolderCheck(checks, sum(1 for v in cache.values() if not isinstance(v, str)))


def _no_slip(c: StateClaims) -> StateCheck:
    """A state without slip and zero-reaction nodes: x_Ts is empty, no critical mu at all."""
    out = StateCheck(c.state, 0, c.proof_state)
    if c.solutions:
        out.failed.append("certified solutions at a state without slip nodes")
    else:
        out.verified.append("no slip node: no critical mu")
    return out


def _prove(folder: pathlib.Path, c: StateClaims, max_side: int) -> Proven | str:
    """What the stored pencil of ``c``'s classification proves, or why it cannot be read."""
    name = f"state_{c.proof_state}.npz"
    try:
        path = inside(folder, FOLDER, name)
        z = read_npz(path, {"A0": ("f", 2), "A1": ("f", 2), "A2": ("f", 2), "log": ("U", 0)},
                     optional=frozenset({"A2"}), max_side=max_side)
    except FileNotFoundError:
        return f"proof file {FOLDER}/{name} missing"
    except UntrustedFile as err:
        return f"proof file {FOLDER}/{name} refused: {err}"
    A0, A1, A2 = z["A0"], z["A1"], z.get("A2")
    if any(M.shape != (c.s, c.s) for M in (A0, A1) + (() if A2 is None else (A2,))):
        return f"{FOLDER}/{name}: the pencil is {A0.shape}, the classification needs {c.s} x {c.s}"
    if c.s > max_side:
        return f"{FOLDER}/{name}: s = {c.s} above the limit {max_side}"
    if not all(np.isfinite(M).all() for M in (A0, A1) + (() if A2 is None else (A2,))):
        return f"{FOLDER}/{name}: the pencil has non-finite entries"
    try:
        raw = parse_json(str(z["log"]), f"{FOLDER}/{name} log")
    except UntrustedFile as err:
        return str(err)
    if (A2 is not None) != c.quadratic:
        return f"{FOLDER}/{name}: " + ("a quadratic pencil for a linear claim" if A2 is not None
                                       else "no curvature term A2 for a quadratic claim")
    if A2 is not None:
        cap = max([x[2] for x in (c.onset,) if x] + [x[0] for x in (c.complete,) if x] + [c.lower_bound] +
                  [s.value for s in c.solutions] + [0.0])
        if not math.isfinite(cap):
            return f"{FOLDER}/{name}: a quadratic claim without a finite cap"
    elif not all(np.array_equal(M[:, b], -M[:, a]) for a, b in c.pairs for M in (A0, A1)):
        return f"{FOLDER}/{name}: the zero-reaction pairs are not exactly opposite columns of the pencil"
    try:
        return _quadratic(A0, A1, A2, raw, c.pairs, cap) if A2 is not None else _linear(A0, A1, raw, c.pairs, c.s)
    except MemoryError:
        raise
    except Exception as err:          # any log the checkers cannot read is a claim not re-verified
        return f"{FOLDER}/{name}: the proof log cannot be re-verified ({type(err).__name__}: {str(err)[:120]})"
