"""The command line's user-facing failure: one ``error:`` line on rank 0 and an exit status.

Shared by the modules behind ``python -m app`` (app/sweep.py; app/cli.py has the same helper
until the one-driver refactor of issue 12), so that none of them imports the CLI module.
"""
from __future__ import annotations

import sys


def fail(msg: str, code: int = 2) -> int:
    """Print ``error: msg`` on rank 0 of COMM_WORLD and return the exit status ``code``."""
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        print(f"error: {msg}", file=sys.stderr)
    return code


class UnreachableLoad(Exception):
    """The prescribed loading path cannot be followed (e.g. the requested normal force cannot be
    reached): a property of the scene, raised identically on every rank; the driver reports it as
    one ``error:`` line (exit 2 from a single study, an error row in a sweep)."""
