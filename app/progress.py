"""Progress bars on rank 0 (tqdm): quiet with --quiet, plain lines when not on a terminal."""
from __future__ import annotations

import sys

from mpi4py import MPI


class _Null:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


class Progress:
    """Factory of progress bars; only rank 0 draws."""

    def __init__(self, enabled: bool = True, comm: MPI.Comm = MPI.COMM_WORLD):
        self.enabled = enabled and comm.rank == 0

    def bar(self, total: int, desc: str):
        if not self.enabled:
            return _Null()
        from tqdm import tqdm
        tty = sys.stderr.isatty()
        return tqdm(total=total, desc=desc, unit="state", file=sys.stderr, leave=tty,
                    mininterval=0.2 if tty else 5.0, ascii=not tty, dynamic_ncols=True)
