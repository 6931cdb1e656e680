"""Progress on rank 0: a tqdm bar on a terminal, plain lines otherwise, nothing with --quiet.

When stderr is not a terminal (a log file, a pipe, CI) a bar would write carriage returns; there
the progress is a plain line ``loading: 120/320 states (38%), 2.1 s`` at most every
``interval`` seconds, plus one line when the task ends. Other ranks never draw.

:meth:`Progress.tasks` is for a stage of few, long work items (the MCEIP-mu classifications): it
shows what runs now, the last result and an estimate of the time left, and a thread repeats the
line at least every ``interval`` seconds while one item runs.
"""
from __future__ import annotations

import math
import os
import sys
import threading
import time

from app.common import hard_stop


class _Null:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


class _NullTasks:
    def start(self, label: str, detail=None) -> None:
        pass

    def finish(self, label: str, cost: float) -> None:
        pass

    def close(self, end: str = "") -> None:
        pass

    def __enter__(self) -> "_NullTasks":
        return self

    def __exit__(self, *exc) -> None:
        pass


class _Lines:
    """Plain progress lines for non-terminal output."""

    def __init__(self, total: int, desc: str, unit: str, stream, interval: float):
        self.total, self.desc, self.unit, self.stream, self.interval = total, desc, unit, stream, interval
        self.n, self.t0 = 0, time.perf_counter()
        self.last = self.t0
        self.closed = False

    def _line(self, end: str = "") -> None:
        if hard_stop.stopping():         # the process is being stopped: its one line is the last
            return
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


def time_left(elapsed: float, done_cost: float, total_cost: float) -> float | None:
    """Seconds left if the remaining work goes at the rate of the work done so far (cost units
    per second); None before any work is done."""
    if done_cost <= 0 or elapsed <= 0:
        return None
    return elapsed * max(total_cost - done_cost, 0.0) / done_cost


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{math.ceil(seconds):.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


class _Tasks:
    """Progress of few long tasks: ``desc: done/total units (pct), elapsed; now ...; last ...;
    about T left (estimate)``. A line is written when a task ends (at most every ``interval``
    seconds) and, from a daemon thread, whenever ``interval`` seconds pass without one.

    ``done()`` returns (tasks done, their cost) over all workers (e.g. all MPI ranks); without it
    the tasks finished here are counted. Costs are relative (only their ratio to ``total_cost``
    enters the estimate)."""

    def __init__(self, total: int, total_cost: float, desc: str, unit: str, write, interval: float, done=None):
        self.total, self.total_cost, self.desc, self.unit = total, float(total_cost), desc, unit
        self.write, self.interval, self._done = write, interval, done
        self.n, self.cost = 0, 0.0
        self.now: tuple[str, float] | None = None
        self.detail = None
        self.last: str | None = None
        self.t0 = self.t_line = time.perf_counter()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name=f"progress: {desc}", daemon=True)
        self._thread.start()

    def start(self, label: str, detail=None) -> None:
        """A task begins here (``label``: what it is, e.g. "s = 180"; ``detail``: a callable
        returning what the task is doing now, e.g. "onset proof, 230 tree nodes", shown in the
        lines written while it runs)."""
        with self._lock:
            self.now = (label, time.perf_counter())
            self.detail = detail

    def finish(self, label: str, cost: float) -> None:
        """The task begun last ends; ``label``: its result (e.g. "s = 180 proven")."""
        with self._lock:
            self.n += 1
            self.cost += cost
            self.now, self.last = None, label
            if time.perf_counter() - self.t_line >= self.interval:
                self._emit()

    def line(self, end: str = "") -> str:
        """The progress line now (``end``: the closing words of the last line, no estimate then)."""
        now = time.perf_counter()
        n, cost = self._done() if self._done is not None else (self.n, self.cost)
        n = min(max(n, self.n), self.total)
        pct = f" ({100.0 * n / self.total:.0f}%)" if self.total else ""
        parts = [f"{self.desc}: {n}/{self.total} {self.unit}s{pct}, {now - self.t0:.1f} s"]
        if self.now is not None:
            what = self.detail() if self.detail is not None else ""
            parts.append(f"now {self.now[0]} ({now - self.now[1]:.0f} s{': ' + what if what else ''})")
        if self.last is not None:
            parts.append(f"last {self.last}")
        if not end:
            left = time_left(now - self.t0, max(cost, self.cost), self.total_cost)
            parts.append("time left: estimating" if left is None else f"about {_duration(left)} left (estimate)")
        return "; ".join(parts) + end

    def _emit(self, end: str = "") -> None:
        self.t_line = time.perf_counter()
        self.write(self.line(end), bool(end))

    def _beat(self) -> None:
        while not self._stop.wait(min(1.0, self.interval / 4)):
            with self._lock:
                if time.perf_counter() - self.t_line >= self.interval:
                    self._emit()

    def close(self, end: str = ", done") -> None:
        """Stop the thread and write the last line (call it while ``done()`` can still be read)."""
        if not self._stop.is_set():
            self._stop.set()
            self._thread.join()
            with self._lock:
                self.now = None
                self._emit(end)

    def __enter__(self) -> "_Tasks":
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close(", done" if exc_type is None else ", stopped")


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
        """A progress bar of ``total`` items (``unit``) named ``desc``, with ``update(n)`` and
        ``close()``: tqdm on a terminal, a plain line at most every ``interval`` seconds otherwise, and
        nothing on ranks other than 0 or when disabled."""
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

    def tasks(self, total: int, desc: str, unit: str = "task", total_cost: float | None = None, done=None):
        """Progress of ``total`` long tasks (see :class:`_Tasks`; ``total_cost`` defaults to one
        unit per task). On a terminal the line is redrawn in place, otherwise one line each time."""
        if not self.enabled:
            return _NullTasks()
        stream = self.stream or sys.stderr
        tty = stream.isatty()

        def write(text: str, final: bool) -> None:
            if hard_stop.stopping():     # the process is being stopped: its one line is the last
                return
            if tty:
                stream.write("\r\033[K" + text + ("\n" if final else ""))
            else:
                stream.write(text + "\n")
            stream.flush()

        return _Tasks(total, total if total_cost is None else total_cost, desc, unit, write, self.interval, done)
