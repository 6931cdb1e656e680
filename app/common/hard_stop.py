"""A Ctrl-C or SIGTERM stops a command-line run within about a second, even while its main thread
is inside a long C call.

The command line's handler (app/common/runtime.py) raises a KeyboardInterrupt where the signal
lands, and the run cleans up on its way out. But Python runs a signal's handler only between two
bytecodes of the main thread: inside one C call (a MUMPS factorisation takes 6 s at 10^6 DOFs)
the handler waits for it, and under mpirun, which answers a Ctrl-C with SIGTERM to the ranks and
SIGKILL a few seconds later, such a run died with its staging folder and lock left behind.

The watchdog here is a daemon thread that reads the signals from Python's wakeup file descriptor
(:func:`signal.set_wakeup_fd`): the interpreter's C-level handler writes each signal's number
there at once, whatever the main thread is doing. When the handler has not taken a SIGINT or
SIGTERM :data:`GRACE` seconds after it arrived, the watchdog calls the cleanups the run
registered (:func:`app.common.interrupt.cleanup_on_hard_stop`: the staging folder and the lock of
a study, a sweep's unfinished case), writes the one line (rank 0) and ends the process with
status 128 + the signal (``os._exit``: the main thread is still inside its C call, and nothing
of the run may go on after the cleanup).

The watchdog can run only while the main thread has released the interpreter. petsc4py's calls
hold it, so the long ones (factorisations) are made through :func:`app.linalg.set_up`, which
releases it; a short call that holds it delays the watchdog as it delays the handler, and the
handler, which Python runs first when the call returns, then takes the signal as usual.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from typing import Callable, Iterator

from app.common import interrupt

#: seconds the main thread has to take a signal before the watchdog stops the run itself (under
#: mpirun, which sends SIGTERM at a Ctrl-C and SIGKILL one second later, the stop must be sooner);
#: none while the main thread is inside a call that releases the interpreter (:func:`released`):
#: it cannot take the signal before the call returns
GRACE = 0.5
#: the signals the watchdog acts on (others written to the wakeup descriptor are ignored)
STOPPING = (signal.SIGINT, signal.SIGTERM)


class Watchdog:
    """The watchdog thread of one process (:func:`start`), reading the wakeup descriptor."""

    def __init__(self, rank: int, armed: Callable[[int], bool]):
        self.rank = rank
        self.armed = armed
        self._read, write = os.pipe()
        os.set_blocking(write, False)          # the C-level handler must never block
        #: the descriptor app/common/runtime.py gives :func:`signal.set_wakeup_fd`
        self.wakeup_fd = write
        self._thread = threading.Thread(target=self._watch, name="signal-watchdog", daemon=True)
        self._thread.start()

    def _watch(self) -> None:
        while True:
            try:
                data = os.read(self._read, 64)        # blocks with the interpreter released
            except OSError:
                return
            if not data:
                return
            for signum in set(data):
                if signum in STOPPING and self.armed(signum) and not self._taken_within(
                        signum, 0.0 if (_INSIDE and _INSIDE[-1]) else GRACE):
                    self.stop(signum)

    @staticmethod
    def _taken_within(signum: int, seconds: float) -> bool:
        """Whether the main thread's handler takes ``signum`` within ``seconds`` (or took it
        already in this run: the run is stopping or putting the signal off, either way responsive)."""
        deadline = time.monotonic() + seconds
        while True:
            if interrupt.TAKEN.get(signum, 0) > 0:
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)

    def stop(self, signum: int) -> None:
        """Undo what the run registered, write the one line, end the process (unless the run's
        own way out has claimed the stop first: then it writes the line)."""
        if not claim():
            return
        left = next((kept for _, kept in reversed(interrupt.CLEANUPS) if kept), None)
        for cleanup, _ in reversed(list(interrupt.CLEANUPS)):
            try:
                cleanup()
            except Exception:                   # noqa: BLE001 - the others must still run
                pass
        if self.rank == 0:
            try:
                sys.stderr.write(interrupt.message(signum, left) + "\n")
                sys.stderr.flush()
            except Exception:                   # noqa: BLE001 - a closed stderr: the status says it
                pass
        os._exit(128 + signum)


def stopping() -> bool:
    """Whether the process is being stopped (:func:`claim` taken): progress lines are no longer
    written, so that the stop's one line is the last."""
    return _CLAIM.locked()


def claim() -> bool:
    """Claim the stop of the process: True for the first caller (the watchdog, or the command
    line's way out after a KeyboardInterrupt), False for the other, which must then write nothing:
    a signal that lands as a released call returns can reach both at once, and the user gets one
    line, not two."""
    return _CLAIM.acquire(blocking=False)


@contextlib.contextmanager
def released(calls_back: bool = False) -> Iterator[None]:
    """Mark a C call made with the interpreter released (app/linalg.py): a signal arriving during
    it stops the run at once, as the main thread can take it only when the call returns; with
    ``calls_back`` (an eigensolve, whose monitors take the interpreter at every iteration and the
    signal with it) the watchdog gives the main thread its grace first."""
    _INSIDE.append(not calls_back)
    try:
        yield
    finally:
        _INSIDE.pop()


def watchdog(rank: int, armed: Callable[[int], bool]) -> Watchdog:
    """The watchdog of this process, started on first use (one per process: the wakeup descriptor
    is process-wide); app/common/runtime.py points the interpreter's wakeup descriptor at its
    ``wakeup_fd``. ``rank``: the MPI rank (rank 0 writes the line); ``armed(signum)``: whether the
    run's handler is still the signal's (it acts only then: a program that put its own handler back
    after a run, the test suite's, keeps its signals)."""
    if not _STARTED:
        _STARTED.append(Watchdog(rank, armed))
    dog = _STARTED[0]
    dog.rank, dog.armed = rank, armed
    return dog


#: the process's watchdog once started (one per process: the wakeup descriptor is process-wide)
_STARTED: list[Watchdog] = []
#: one entry per released C call the main thread is inside (:func:`released`): True when the main
#: thread cannot take a signal before the call returns
_INSIDE: list[bool] = []
#: held by whoever stops the process (:func:`claim`)
_CLAIM = threading.Lock()
