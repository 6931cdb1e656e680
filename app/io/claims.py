"""The claims of a results.json about MCEIP-mu, read as untrusted data (paper eqs. (21)-(23)).

What results.json calls proven at a state (docs/proofs.md): the **onset** (no critical mu in
``[0, cap]``, or the smallest one inside ``onset.enclosure``), the **complete list** on
``complete.interval``, each **certified solution**, the **lower bound**
``certificate.detail.lower_bound``; ``certified: true`` claims the onset and the list.

:func:`read_results` reads results.json into the typed :class:`app.io.result.StudyResult`:
bounded in size, then validated strictly with its models (:func:`app.io.result.validate`, format
3). :func:`state_claims` then reads each state's claims into :class:`StateClaims`, checking what
the models allow but a claim cannot be (a negative index or count, a number that is NaN, an
interval that is not ``[low, high]``, a proven value without its enclosure, ...). A document that
is not this app's results is a :class:`MalformedResults` naming the JSON path, never a traceback.
:mod:`app.io.check` verifies the claims.
"""
from __future__ import annotations

import math
import pathlib
import reprlib
from dataclasses import dataclass

from app.io.result import Certificate, MceipMuResult, StateResult, StudyResult
from app.io.untrusted import RESULTS_MAX_BYTES, inside, parse_json, read_bytes


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


def state_claims(study: StudyResult) -> list[StateClaims]:
    """The MCEIP-mu claims of every state of ``study`` (:func:`read_results`); :class:`MalformedResults`
    when a claim is not one this app can make."""
    return [_claims(st, f"states[{k}]") for k, st in enumerate(study.states)]


def _index(v: int | None, where: str, what: str) -> None:
    if v is not None and v < 0:
        raise _bad(where, f"{v!r} is not {what}")


def _claims(st: StateResult, where: str) -> StateClaims:
    _index(st.index, f"{where}.index", "a state index")
    shared = st.analyses_shared_with
    _index(shared, f"{where}.analyses_shared_with", "a state index")
    cls = st.classification
    for key in ("slip", "zero"):
        _index(getattr(cls, key), f"{where}.classification.{key}", "a count")
    statuses = tuple(n.status for n in st.nodes)
    # the record as written, whether it says it failed or not: whatever it calls proven is a claim
    a = st.analyses.mceip_mu
    empty = StateClaims(st.index, st.index if shared is None else shared, cls.slip, cls.zero, statuses,
                        False, None, None, 0.0, ())
    if a is None:
        return empty
    w = f"{where}.analyses.mceip_mu"
    cert = a.certificate
    onset = None
    o = a.onset
    if o is not None and o.proven:
        value = json_number(o.value, f"{w}.onset.value", allow_none=True)
        enc = None if o.enclosure is None else _pair(o.enclosure, f"{w}.onset.enclosure")
        if value is not None and enc is None:
            raise _bad(f"{w}.onset", "a proven onset value without its enclosure")
        onset = (value, enc, _claim_cap(cert, a, w))
    complete = None
    c = a.complete
    if c is not None and c.proven:
        lo, hi = _pair(c.interval, f"{w}.complete.interval")
        _index(c.count, f"{w}.complete.count", "a count")
        complete = (hi, c.count)
    if a.certified is True and (onset is None or complete is None):
        raise _bad(w, "certified: true without a proven onset and a proven complete list")
    detail = (cert.detail if cert is not None else None) or {}
    lb = json_number(detail.get("lower_bound", 0.0), f"{w}.certificate.detail.lower_bound") or 0.0
    claimed = []
    for j, d in enumerate(a.solutions):
        if d.certified is not True:
            continue
        value = json_number(d.value, f"{w}.solutions[{j}].value")
        enc = None if d.enclosure is None else _pair(d.enclosure, f"{w}.solutions[{j}].enclosure")
        support = None
        if cls.zero == 0 and len(d.pattern) == cls.slip:
            support = tuple(i for i, p in enumerate(d.pattern) if p == "slip")
        claimed.append(SolutionClaim(value, enc, support))
    quadratic = (a.model_extra or {}).get("quadratic") is True
    return StateClaims(st.index, empty.proof_state, cls.slip, cls.zero, statuses, quadratic,
                       onset, complete, max(lb, 0.0), tuple(claimed))


def _claim_cap(cert: Certificate | None, a: MceipMuResult, where: str) -> float:
    """The cap a proven onset speaks about: the certificate's, else the complete interval's end,
    else the end of the certificate's interval (null there: infinity)."""
    cap = None if cert is None else cert.cap
    if cap is None:
        if a.complete is not None and a.complete.interval is not None:
            return _pair(a.complete.interval, f"{where}.complete.interval")[1]
        interval = (None if cert is None else cert.interval) or [0.0, math.inf]
        if len(interval) != 2:
            raise _bad(f"{where}.certificate.interval", f"expected [low, high], found {interval!r:.60}")
        cap = interval[1]
    v = json_number(cap, f"{where}.certificate.cap", allow_none=True)
    return math.inf if v is None else v


def _short(value) -> str:
    """``repr(value)`` cut short for an error line, however large ``value`` is (never built in full)."""
    r = reprlib.Repr()
    r.maxlevel, r.maxdict, r.maxlist, r.maxtuple, r.maxset = 2, 3, 3, 3, 3
    r.maxstring = r.maxother = r.maxlong = 40
    return r.repr(value)


def _where(loc: tuple) -> str:
    """A pydantic error location as a JSON path of the claims' messages: ``states[3].analyses``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _problem(err) -> str:
    """The one line of a results.json that the models refuse: the first problem that is not a
    missing key (a value of the wrong kind says most about a foreign document), its path and the
    value found, and how many other problems there are."""
    errors = err.errors(include_url=False)
    first = next((e for e in errors if e["type"] != "missing"), errors[0])
    where = _where(tuple(first.get("loc", ()))) or "the document"
    got = "" if first["type"] == "missing" else f" (got {_short(first.get('input'))})"
    more = f"; and {len(errors) - 1} other problem(s)" if len(errors) > 1 else ""
    return f"results.json {where}: {first.get('msg', 'invalid')}{got}{more}"


def read_results(folder: pathlib.Path) -> StudyResult:
    """results.json of ``folder`` as the typed study: at most :data:`~app.io.untrusted.RESULTS_MAX_BYTES`
    bytes of a regular file (:class:`~app.io.untrusted.UntrustedFile` otherwise, FileNotFoundError
    when missing), JSON (:class:`~app.io.untrusted.UntrustedFile`: not JSON, nested too deeply),
    and valid results.json of this format, read strictly (:class:`MalformedResults`)."""
    from pydantic import ValidationError

    from app.io.document import from_document
    from app.io.result import validate
    path = inside(folder, "results.json")
    text = read_bytes(path, RESULTS_MAX_BYTES)
    doc = parse_json(text, str(path))
    if not isinstance(doc, dict):
        raise MalformedResults(f"results.json: expected an object, found {type(doc).__name__}")
    try:
        validate(text)              # strict; its null numbers are not yet the non_finite block's values
        data = from_document(doc)   # a new dictionary: the text and the parsed document can go
        del text, doc
        return StudyResult.from_dict(data)
    except ValidationError as err:
        raise MalformedResults(_problem(err)) from None
    except (ValueError, TypeError, KeyError) as err:
        raise MalformedResults(f"results.json: {err}") from None
