"""User-facing failures shared by the modules behind ``python -m app`` (app/cli/main.py, app/study/driver.py,
app/study/sweep.py, app/study/refinement.py): one ``error:`` line on rank 0 and an exit status, so that none of
them imports the CLI module.

Exit status: 0 ok, 2 a user mistake, 3 the study ran but some states failed, 4 the results could
not be written.
"""
from __future__ import annotations

import sys

EXIT_OK, EXIT_USER, EXIT_INCOMPLETE, EXIT_WRITE = 0, 2, 3, 4


def point_text(xy, size: float) -> str:
    """``(x, y)`` for messages, coordinates at round-off of ``size`` (the body's) shown as 0."""
    return "(" + ", ".join(f"{(v if abs(v) > 1e-12 * size else 0.0):.6g}" for v in map(float, xy)) + ")"


def fail(msg: str, code: int = EXIT_USER) -> int:
    """Print ``error: msg`` on rank 0 of COMM_WORLD and return the exit status ``code``."""
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        print(f"error: {msg}", file=sys.stderr)
    return code


class UnreachableLoad(Exception):
    """The prescribed loading path cannot be followed (e.g. the requested normal force cannot be
    reached): a property of the scene, raised identically on every rank; the driver reports it as
    one ``error:`` line (exit 2 from a single study, an error row in a sweep). ``key``: the part of
    the scene the message blames (default ``loading``; None when the message names its key)."""

    def __init__(self, msg: str, key: str | None = "loading"):
        super().__init__(msg)
        self.key = key
