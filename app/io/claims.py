"""The claims of a results.json about MCEIP-mu, read as untrusted data (paper eqs. (21)-(23)).

What results.json calls proven at a state (docs/proofs.md): the **onset** (no critical mu in
``[0, cap]``, or the smallest one inside ``onset.enclosure``), the **complete list** on
``complete.interval``, each **certified solution**, the **lower bound**
``certificate.detail.lower_bound``; ``certified: true`` claims the onset and the list. Each is read
into :class:`StateClaims` with its types checked: a document that is not this app's results is a
:class:`MalformedResults` naming the JSON path, never a traceback. :mod:`app.io.check` verifies them.
"""
from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass

from app.io.untrusted import RESULTS_MAX_BYTES, inside, load_json


class MalformedResults(ValueError):
    """results.json cannot be read as this app's results; ``str(err)`` is one line."""


@dataclass(frozen=True)
class SolutionClaim:
    """A solution results.json marks ``certified``: its value, stated enclosure and support."""

    value: float
    enclosure: tuple[float, float] | None
    support: tuple[int, ...] | None


@dataclass(frozen=True)
class StateClaims:
    """What results.json calls proven about MCEIP-mu at one state."""

    state: int
    proof_state: int                      # the state whose proof file holds the pencil
    slip: int
    zero: int
    statuses: tuple[str, ...]             # the classification's node statuses
    quadratic: bool
    onset: tuple[float | None, tuple[float, float] | None, float] | None  # (value, enclosure, cap) or None
    complete: tuple[float, int | None] | None                              # (interval end, count) or None
    lower_bound: float
    solutions: tuple[SolutionClaim, ...]

    @property
    def s(self) -> int:
        """The pencil's size: one column per slip node, three (a, b, N) per zero-reaction node."""
        return self.slip + 3 * self.zero

    @property
    def pairs(self) -> list[tuple[int, int]]:
        """The halves ``(a, b)`` of each zero-reaction node's split tangential rate, at their fixed
        places after the slip columns (app/analyses/pencils/reduced.py ``split_pencil``)."""
        return [(self.slip + 3 * k, self.slip + 3 * k + 1) for k in range(self.zero)]

    @property
    def any(self) -> bool:
        """Whether the state claims anything proven."""
        return self.onset is not None or self.complete is not None or self.lower_bound > 0 or bool(self.solutions)


def _bad(where: str, what: str) -> MalformedResults:
    return MalformedResults(f"results.json {where}: {what}")


def json_number(x, where: str, allow_none: bool = False) -> float | None:
    """``x`` as a float (``where`` names it in the error): a JSON number, not a boolean nor NaN."""
    if x is None and allow_none:
        return None
    if isinstance(x, bool) or not isinstance(x, (int, float)) or math.isnan(float(x)):
        raise _bad(where, f"{x!r} is not a number")
    return float(x)


def json_object(x, where: str) -> dict:
    """``x`` when it is a JSON object (``where`` names it in the error)."""
    if not isinstance(x, dict):
        raise _bad(where, f"expected an object, found {type(x).__name__}")
    return x


def _pair(x, where: str) -> tuple[float, float]:
    if not isinstance(x, list) or len(x) != 2:
        raise _bad(where, f"expected [low, high], found {x!r:.60}")
    lo, hi = json_number(x[0], where), json_number(x[1], where)
    if not lo <= hi:
        raise _bad(where, f"[{lo}, {hi}] is not an interval")
    return lo, hi


def state_claims(doc: dict) -> list[StateClaims]:
    """The MCEIP-mu claims of every state of a results document (:func:`app.io.document.from_document`
    of results.json); :class:`MalformedResults` when its structure is not this app's."""
    states = doc.get("states")
    if not isinstance(states, list):
        raise _bad("states", f"expected a list of states, found {type(states).__name__}")
    out = []
    for k, st in enumerate(states):
        out.append(_claims(json_object(st, f"states[{k}]"), f"states[{k}]"))
    return out


def _claims(st: dict, where: str) -> StateClaims:
    index = st.get("index")
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        raise _bad(f"{where}.index", f"{index!r} is not a state index")
    shared = st.get("analyses_shared_with")
    if shared is not None and (isinstance(shared, bool) or not isinstance(shared, int) or shared < 0):
        raise _bad(f"{where}.analyses_shared_with", f"{shared!r} is not a state index")
    cls = json_object(st.get("classification"), f"{where}.classification")
    counts = {}
    for key in ("slip", "zero"):
        v = cls.get(key, 0)
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise _bad(f"{where}.classification.{key}", f"{v!r} is not a count")
        counts[key] = v
    nodes = st.get("nodes", [])
    if not isinstance(nodes, list):
        raise _bad(f"{where}.nodes", "expected a list")
    statuses = tuple(str(json_object(n, f"{where}.nodes").get("status")) for n in nodes)
    analyses = json_object(st.get("analyses", {}), f"{where}.analyses")
    block = analyses.get("mceip_mu")
    empty = StateClaims(index, index if shared is None else shared, counts["slip"], counts["zero"], statuses,
                        False, None, None, 0.0, ())
    if block is None:
        return empty
    a = json_object(block, f"{where}.analyses.mceip_mu")
    w = f"{where}.analyses.mceip_mu"
    cert = a.get("certificate") or {}
    cert = json_object(cert, f"{w}.certificate")
    onset = None
    o = a.get("onset")
    if o is not None and json_object(o, f"{w}.onset").get("proven") is True:
        value = json_number(o.get("value"), f"{w}.onset.value", allow_none=True)
        enc = None if o.get("enclosure") is None else _pair(o["enclosure"], f"{w}.onset.enclosure")
        if value is not None and enc is None:
            raise _bad(f"{w}.onset", "a proven onset value without its enclosure")
        cap = _claim_cap(cert, a, w)
        onset = (value, enc, cap)
    complete = None
    c = a.get("complete")
    if c is not None and json_object(c, f"{w}.complete").get("proven") is True:
        lo, hi = _pair(c.get("interval"), f"{w}.complete.interval")
        count = c.get("count")
        if count is not None and (isinstance(count, bool) or not isinstance(count, int) or count < 0):
            raise _bad(f"{w}.complete.count", f"{count!r} is not a count")
        complete = (hi, count)
    if a.get("certified") is True and (onset is None or complete is None):
        raise _bad(w, "certified: true without a proven onset and a proven complete list")
    detail = json_object(cert.get("detail") or {}, f"{w}.certificate.detail")
    lb = json_number(detail.get("lower_bound", 0.0), f"{w}.certificate.detail.lower_bound") or 0.0
    sols = a.get("solutions") or []
    if not isinstance(sols, list):
        raise _bad(f"{w}.solutions", "expected a list")
    claimed = []
    for j, d in enumerate(sols):
        d = json_object(d, f"{w}.solutions[{j}]")
        if d.get("certified") is not True:
            continue
        value = json_number(d.get("value"), f"{w}.solutions[{j}].value")
        enc = None if d.get("enclosure") is None else _pair(d["enclosure"], f"{w}.solutions[{j}].enclosure")
        pattern = d.get("pattern")
        support = None
        if isinstance(pattern, list) and counts["zero"] == 0 and len(pattern) == counts["slip"]:
            support = tuple(i for i, p in enumerate(pattern) if p == "slip")
        claimed.append(SolutionClaim(value, enc, support))
    return StateClaims(index, empty.proof_state, counts["slip"], counts["zero"], statuses, a.get("quadratic") is True,
                       onset, complete, max(lb, 0.0), tuple(claimed))


def _claim_cap(cert: dict, a: dict, where: str) -> float:
    """The cap a proven onset speaks about: the certificate's, else the complete interval's end."""
    cap = cert.get("cap")
    if cap is None:
        c = a.get("complete") or {}
        if isinstance(c, dict) and c.get("interval") is not None:
            return _pair(c["interval"], f"{where}.complete.interval")[1]
        cap = (cert.get("interval") or [0.0, math.inf])[1]
    v = json_number(cap, f"{where}.certificate.cap", allow_none=True)
    return math.inf if v is None else v


def read_results(folder: pathlib.Path) -> dict:
    """results.json of ``folder``, bounded and checked (:class:`UntrustedFile`, :class:`MalformedResults`)."""
    from app.io.document import from_document
    doc = load_json(inside(folder, "results.json"), RESULTS_MAX_BYTES)
    if not isinstance(doc, dict):
        raise MalformedResults(f"results.json: expected an object, found {type(doc).__name__}")
    try:
        return from_document(doc)
    except (ValueError, TypeError, KeyError) as err:
        raise MalformedResults(f"results.json: {err}") from None
