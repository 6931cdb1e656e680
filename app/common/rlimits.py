"""Resource limits a process sets for a child it starts, never above what it inherited.

A batch system (``ulimit -v``, ``ulimit -f`` in a job script) often sets hard limits. An
unprivileged process can lower a hard limit but never raise it, and a ``setrlimit`` above it
fails (in a ``preexec_fn`` the child is then never started). :func:`within_inherited` computes,
in the parent, limits that are each the lower of what is wanted and what is inherited, and says
which wanted limits could not be had; :func:`setter` applies such computed limits in the child
between fork and exec.
"""
from __future__ import annotations

import resource
from collections.abc import Callable, Mapping
from dataclasses import dataclass

INFINITY = resource.RLIM_INFINITY

#: names of the limits in messages
NAMES = {resource.RLIMIT_AS: "address space (ulimit -v)", resource.RLIMIT_FSIZE: "file size (ulimit -f)",
         resource.RLIMIT_CPU: "CPU time (ulimit -t)", resource.RLIMIT_CORE: "core file size (ulimit -c)"}


@dataclass(frozen=True)
class Limit:
    """One limit to set: ``(soft, hard)``, each a count or :data:`INFINITY`."""

    soft: int
    hard: int


def _lower(a: int, b: int) -> int:
    """The lower of two limit values (:data:`INFINITY` is above every count)."""
    if a == INFINITY:
        return b
    if b == INFINITY:
        return a
    return min(a, b)


def lowered(wanted: Limit, inherited: Limit) -> Limit:
    """``wanted`` lowered to ``inherited``: neither the hard limit nor the soft one goes above the
    inherited value of its kind, and the soft limit never above the new hard one."""
    hard = _lower(wanted.hard, inherited.hard)
    return Limit(_lower(_lower(wanted.soft, inherited.soft), hard), hard)


#: limits counted in bytes (the others: CPU seconds)
BYTES = (resource.RLIMIT_AS, resource.RLIMIT_FSIZE, resource.RLIMIT_CORE)


def _text(res: int, value: int) -> str:
    if value == INFINITY:
        return "unlimited"
    return f"{value / 2**30:.3g} GiB" if res in BYTES else f"{value} s"


def within_inherited(wanted: Mapping[int, Limit],
                     current: Callable[[int], tuple[int, int]] = resource.getrlimit,
                     ) -> tuple[dict[int, Limit], list[str]]:
    """(limits to set, notes): each wanted limit lowered to this process's own (``current``,
    which a child inherits); a note for each wanted soft limit that the inherited ones cap lower."""
    out, notes = {}, []
    for res, want in wanted.items():
        got = lowered(want, Limit(*current(res)))
        out[res] = got
        if got.soft != _lower(want.soft, want.hard):
            notes.append(f"{NAMES.get(res, f'limit {res}')}: {_text(res, want.soft)} wanted, the inherited "
                         f"limit allows {_text(res, got.soft)}")
    return out, notes


def setter(limits: Mapping[int, Limit]) -> Callable[[], None]:
    """A ``preexec_fn`` setting ``limits`` (computed by :func:`within_inherited`: each within the
    inherited hard limit, so ``setrlimit`` cannot fail for lack of privilege)."""
    items = [(res, (lim.soft, lim.hard)) for res, lim in limits.items()]

    def apply() -> None:
        for res, pair in items:
            resource.setrlimit(res, pair)
    return apply
