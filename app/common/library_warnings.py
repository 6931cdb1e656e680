"""Warnings raised by libraries inside a study, explained instead of printed raw.

numpy reports floating-point trouble as a ``RuntimeWarning`` located in its own source
(e.g. "numpy/linalg/linalg.py:2139: RuntimeWarning: overflow encountered in det"), which tells a user
neither what the app was doing nor whether an answer is affected. Inside :func:`explained` every
warning is caught instead; each distinct one (category, message, the calling app function) is
kept once with a count and:

- when it is known (:data:`KNOWN`: its cause in that function, and why the answers are
  unaffected), logged at INFO;
- otherwise logged as a WARNING naming the app function and line that called the library.

Warnings that say nothing about the computation (:data:`IGNORED_IN_LIBRARY`: a library's file
hygiene, such as FFCx's on a cold JIT cache) are logged at DEBUG only.

:func:`app.study.run.study` lists both kinds in results.json ``library_warnings`` (merged over
the ranks, :func:`merged`) and adds the unknown ones to the study's ``warnings`` (the summary,
the report).
"""
from __future__ import annotations

import contextlib
import logging
import os
import sys
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field

from app.common import runtime

log = logging.getLogger(__name__)

#: (message, app function) -> why the warning there does not affect the answers (none known today:
#: the dense search's singular-Jacobian test uses slogdet, which cannot overflow as det did)
KNOWN: dict[tuple[str, str], str] = {}

#: (category, library file) -> why a warning of that category raised there says nothing about the
#: computation, whatever its message (which names a file): logged at DEBUG, not recorded. An empty
#: library file matches every library.
IGNORED_IN_LIBRARY: dict[tuple[str, str], str] = {
    # A file or socket a library left unclosed, which CPython closes when the object is collected:
    # FFCx claims each new C file of its JIT cache with ``open(name, "x")`` and drops the handle
    # (ffcx 0.5, codegeneration/jit.py get_cached_module); threadpoolctl's reading of
    # /proc/self/maps is left open when a Ctrl-C's KeyboardInterrupt lands inside it. File
    # hygiene only: no number of the study depends on it.
    ("ResourceWarning", ""):
        "a library left a file unclosed (Python closes it when the object is collected; file hygiene "
        "only, e.g. FFCx's placeholder of a new C file of its JIT cache)",
}

_LIBRARY_DIRS = tuple({os.path.dirname(os.__file__), os.path.dirname(warnings.__file__)})


def _is_library(filename: str) -> bool:
    """Code of an installed package or the standard library (and their pseudo-files such as
    ``<__array_function__ internals>``), as opposed to the app (or a script) calling them."""
    return ("site-packages" in filename or "dist-packages" in filename or filename.startswith(_LIBRARY_DIRS)
            or (filename.startswith("<") and filename not in ("<string>", "<stdin>")))


def _caller(depth: int = 3) -> tuple[str, str, int]:
    """(file, function, line) of the innermost frame outside the libraries: the app code whose
    library call warned."""
    f = sys._getframe(depth)
    while f is not None and _is_library(f.f_code.co_filename):
        f = f.f_back
    if f is None:
        return "?", "?", 0
    name = f.f_code.co_filename
    here = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the repository
    if name.startswith(here + os.sep):
        name = os.path.relpath(name, here)
    return name, f.f_code.co_name, f.f_lineno


@dataclass
class Recorder:
    """The distinct warnings seen, in order, with their counts."""

    seen: dict[tuple, dict] = field(default_factory=dict)

    def add(self, category: type, message: str, library_file: str, library_line: int) -> dict:
        """Count one warning of ``category`` with ``message``, raised at ``library_file:library_line``
        on behalf of the app function found on the stack, and return its record: ``category``,
        ``message``, ``where`` (the app's file, line and function), ``library``, ``count`` and
        ``explanation`` (from :data:`KNOWN`, None for an unknown warning)."""
        where, function, line = _caller()
        key = (category.__name__, message, where, function)
        rec = self.seen.get(key)
        if rec is None:
            rec = {"category": category.__name__, "message": message, "where": f"{where}:{line} ({function})",
                   "library": f"{library_file}:{library_line}", "count": 0,
                   "explanation": KNOWN.get((message, function))}
            self.seen[key] = rec
        rec["count"] += 1
        return rec

    def as_list(self) -> list[dict]:
        """Copies of the records, in the order the warnings were first seen."""
        return [dict(r) for r in self.seen.values()]


def _ignored(category: type, library_file: str) -> str | None:
    """Why a ``category`` warning raised in ``library_file`` is ignored (:data:`IGNORED_IN_LIBRARY`), or None."""
    for (name, suffix), why in IGNORED_IN_LIBRARY.items():
        if category.__name__ == name and library_file.replace(os.sep, "/").endswith(suffix):
            return why
    return None


def describe(rec: dict, count: bool = True) -> str:
    """One line for a user: what warned, where in the app (how often), and what it means."""
    head = f"{rec['category']} '{rec['message']}' in {rec['where']}" + (f", {rec['count']} time(s)" if count else "")
    if rec.get("explanation"):
        return f"{head}: {rec['explanation']}"
    return (f"{head} (raised by {rec['library']}): not a known, harmless case; the answers computed there "
            f"may be affected: please report it")


@contextlib.contextmanager
def explained() -> Iterator[Recorder]:
    """Catch every warning raised in the block into the yielded :class:`Recorder`, each logged
    when first seen (see the module docstring)."""
    rec = Recorder()

    def show(message, category, filename, lineno, file=None, line=None):
        why = _ignored(category, filename)
        if why:
            log.debug("%s %s: %s", category.__name__, message, why)
            return
        first = rec.add(category, str(message), filename, lineno)
        if first["count"] == 1:
            if first["explanation"]:
                log.info("%s", describe(first, count=False))
            else:
                log.warning("%s", describe(first, count=False))

    with runtime.showing_warnings(show):
        yield rec


def merged(parts: list[list[dict]]) -> list[dict]:
    """The records of several ranks as one list (counts summed, first appearance order)."""
    out: dict[tuple, dict] = {}
    for part in parts:
        for r in part:
            key = (r["category"], r["message"], r["where"])
            if key in out:
                out[key]["count"] += r["count"]
            else:
                out[key] = dict(r)
    return list(out.values())
