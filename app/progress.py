"""Progress on rank 0: a tqdm bar on a terminal, plain lines otherwise, nothing with --quiet.

When stderr is not a terminal (a log file, a pipe, CI) a bar would write carriage returns; there
the progress is a plain line ``loading: 120/320 states (38%), 2.1 s`` at most every
``interval`` seconds, plus one line when the task ends. Other ranks never draw.
"""
from __future__ import annotations

import os
import sys
import time


class _Null:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


class _Lines:
    """Plain progress lines for non-terminal output."""

    def __init__(self, total: int, desc: str, unit: str, stream, interval: float):
        self.total, self.desc, self.unit, self.stream, self.interval = total, desc, unit, stream, interval
        self.n, self.t0 = 0, time.perf_counter()
        self.last = self.t0
        self.closed = False

    def _line(self, end: str = "") -> None:
        pct = f" ({100.0 * self.n / self.total:.0f}%)" if self.total else ""
        print(f"{self.desc}: {self.n}/{self.total} {self.unit}s{pct}, {time.perf_counter() - self.t0:.1f} s{end}",
              file=self.stream, flush=True)

    def update(self, n: int = 1) -> None:
        self.n += n
        now = time.perf_counter()
        if now - self.last >= self.interval:
            self.last = now
            self._line()

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._line(", done")


class Progress:
    """Factory of progress bars; only rank 0 draws."""

    def __init__(self, enabled: bool = True, comm=None, stream=None, interval: float = 5.0):
        if comm is None:
            from mpi4py import MPI
            comm = MPI.COMM_WORLD
        self.enabled = enabled and comm.rank == 0
        self.stream = stream
        self.interval = interval

    def bar(self, total: int, desc: str, unit: str = "state"):
        if not self.enabled:
            return _Null()
        stream = self.stream or sys.stderr
        if not stream.isatty():
            return _Lines(total, desc, unit, stream, self.interval)
        from tqdm import tqdm
        try:
            width = os.get_terminal_size(stream.fileno()).columns
        except (OSError, AttributeError, ValueError):
            width = 0
        # a terminal that reports no size (e.g. a pty without a window) gets a fixed width
        return tqdm(total=total, desc=desc, unit=unit, file=stream, leave=True, mininterval=0.2,
                    dynamic_ncols=width > 0, ncols=None if width > 0 else 100)
