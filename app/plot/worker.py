"""Drawing processes started before they are needed (pictures add at most 2 s).

After a run, rank 0 draws the plots (matplotlib) and the screenshots (pyvista/VTK). They are
drawn by child interpreters, ``python -m app.plot.worker KIND [ARG]``:

* VTK cannot run in a process that has loaded DOLFINx (see app/plot/screenshots.py), and a
  drawing failure must not take the study's results with it;
* each child imports its libraries and warms up (fonts, an OpenGL context with its shaders
  compiled) while the study runs, instead of after it;
* the plots and the screenshots are drawn at the same time, one child each.

Plain ``subprocess`` children rather than a ``concurrent.futures`` process pool: a pool's workers
start in the run's process group (an initializer could call ``setsid`` only after the
interpreter's start-up, the very moment a Ctrl-C at the terminal prints a traceback in a child),
and a pool would pickle the job instead of handing over the file that ``render`` reads too.

A child warms up, then reads one job file name on its standard input, as bytes ending in a NUL
byte (any path, a newline in it too; EOF without a name: no job, it exits), draws, and prints
``{"files": [...], "notes": [...], "seconds": ...}`` as its last line. A child never prints a
traceback: any failure, from the imports on, is the one line ``{"error": ..., "errno": ...}``
and exit status 1; the parent makes it a note and a warning, or, for a full disk (ENOSPC), the
run's own "no space left" error (exit status 4).
"""
from __future__ import annotations

import json
import logging
import os
import pathlib
import signal
import subprocess
import sys
import time

from app.common.cache import cache_dir, usable_dir
from app.common.errors import WRITE_LIMIT_ERRNOS, write_limit

KINDS = ("plots", "screenshots")
PARENT_VARIABLE = "APP_DRAWING_PARENT_PID"
NICE = 5              # niceness added to the drawing processes

log = logging.getLogger(__name__)


class Worker:
    """One drawing child process of ``kind`` ("plots" or "screenshots"; ``arg``: the screenshots'
    resolution ``WxH``)."""

    def __init__(self, kind: str, arg: str = ""):
        if kind not in KINDS:
            raise ValueError(f"unknown drawing process kind {kind!r}")
        self.kind, self.arg = kind, arg
        # not an MPI process: drop the launcher's variables so nothing in the child joins the MPI job
        env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_", "PMI_", "OPAL_", "HYDRA_"))}
        root = str(pathlib.Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        env[PARENT_VARIABLE] = str(os.getpid())
        env.update(_cache_folders(env))
        # A session of its own: a Ctrl-C at the terminal (sent to the whole foreground process
        # group) is for the run, not for a child still importing its libraries, where a SIGINT
        # would print a traceback before any handler exists. The run stops its children itself
        # (close_unused), and a child dies with the run (_die_with_parent).
        self.proc = subprocess.Popen([sys.executable, "-m", "app.plot.worker", kind] + ([arg] if arg else []),
                                     env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, start_new_session=True)

    def submit(self, job: pathlib.Path) -> "Worker":
        """Hand over the job file (the child starts drawing; does not wait): its path's bytes and a
        NUL byte, which no path holds, so that any path works (a newline too)."""
        try:
            self.proc.stdin.write(os.fsencode(job) + b"\0")
            self.proc.stdin.close()
        except BrokenPipeError:         # the child died while warming up: wait() reports its status
            pass
        return self

    def wait(self) -> tuple[list[pathlib.Path], list[str], float | None]:
        """(files, notes, drawing seconds) once the child has finished. A failure is a note, and a
        warning line; a full disk in the child is raised here as the ``OSError`` it was (ENOSPC),
        so that the run ends as on any full disk."""
        stdout = self.proc.stdout.read()
        self.proc.stdout.close()
        code = self.proc.wait()
        reply = _reply(stdout)
        if code == 0 and "files" in reply:
            return [pathlib.Path(f) for f in reply["files"]], list(reply["notes"]), reply["seconds"]
        if reply.get("errno") in WRITE_LIMIT_ERRNOS:
            raise OSError(reply["errno"], os.strerror(reply["errno"]), reply.get("filename"))
        why = reply.get("error") or f"the drawing process {_status_text(code)}"
        note = f"{self.kind} failed: {why}; the results are complete, redraw with: python -m app render"
        log.warning("%s", note)
        return [], [note], None

    def close(self, kill: bool = False) -> None:
        """Stop a child that got no job (its standard input closes: it exits; ``kill``: at once,
        as when the run is interrupted)."""
        if kill and self.proc.poll() is None:
            self.proc.kill()
        if self.proc.poll() is None:
            try:
                if not self.proc.stdin.closed:
                    self.proc.stdin.close()
                self.proc.wait(timeout=10)
            except (subprocess.TimeoutExpired, BrokenPipeError):
                self.proc.kill()
                self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout):
            if f is not None and not f.closed:
                f.close()


def _cache_folders(env: dict[str, str]) -> dict[str, str]:
    """The cache and configuration folders of a drawing child: ``XDG_CACHE_HOME`` the app's
    writable cache folder (app/common/cache.py: the user's, else this user's folder in the
    temporary folder), so that matplotlib's font cache and Mesa's shader cache (VTK's off-screen
    OpenGL) neither print warnings nor go to a new temporary folder each time; ``MPLCONFIGDIR``
    the same folder's ``matplotlib`` when matplotlib's configuration folder
    (``$XDG_CONFIG_HOME/matplotlib``, default ``~/.config/matplotlib``) cannot be written."""
    out = {"XDG_CACHE_HOME": str(cache_dir(""))}
    if not env.get("MPLCONFIGDIR"):
        config = env.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
        if not os.path.isabs(config) or usable_dir(pathlib.Path(config) / "matplotlib") is not None:
            out["MPLCONFIGDIR"] = str(cache_dir("matplotlib"))
    return out


_STARTED: dict[tuple[str, str], Worker] = {}


def prestart(kind: str, arg: str = "") -> None:
    """Start a ``kind`` child now; :func:`take` hands it out, :func:`close_unused` stops it."""
    if (kind, arg) not in _STARTED:
        _STARTED[(kind, arg)] = Worker(kind, arg)


def take(kind: str, arg: str = "") -> Worker:
    """The child started by :func:`prestart` for (kind, arg), else a new one."""
    return _STARTED.pop((kind, arg), None) or Worker(kind, arg)


def close_unused(kill: bool = False) -> None:
    """Stop every child started by :func:`prestart` and not taken (``kill``: without waiting for
    them to finish warming up)."""
    while _STARTED:
        _STARTED.popitem()[1].close(kill)


def _die_with_parent() -> None:
    """Linux: this child is killed when the run that started it dies, even by SIGKILL, so that it
    never draws into a staging folder nobody will commit (prctl PR_SET_PDEATHSIG)."""
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, 9)            # PR_SET_PDEATHSIG = 1, SIGKILL = 9
    except (OSError, AttributeError):
        return
    if os.getppid() != int(os.environ.get(PARENT_VARIABLE, os.getppid())):
        os._exit(0)                 # the run died before the request took effect


def _reply(stdout: bytes) -> dict:
    """The child's reply, the JSON object on its last line of output ({} if there is none)."""
    lines = stdout.strip().splitlines()
    try:
        reply = json.loads(lines[-1]) if lines else {}
    except ValueError:
        return {}
    return reply if isinstance(reply, dict) else {}


def _status_text(code: int) -> str:
    """How a child process ended, from its exit status (negative: the signal that killed it)."""
    if code >= 0:
        return f"exited with status {code}"
    try:
        return f"was killed by {signal.Signals(-code).name}"
    except ValueError:
        return f"was killed by signal {-code}"


def _failure(err: BaseException) -> dict:
    """The reply of a child whose drawing failed: one line, the ``errno`` (a full disk is told
    apart by the parent) and the file it was writing."""
    text = " ".join(str(err).split())[:300]
    reply = {"error": f"{type(err).__name__}: {text}" if text else type(err).__name__}
    if isinstance(err, OSError) and err.errno is not None:
        reply["errno"] = err.errno
        if err.filename is not None:
            reply["filename"] = os.fsdecode(err.filename)
    elif write_limit(err) is not None:           # as h5py and VTK say it
        reply["errno"] = write_limit(err)
    return reply


def _job_path(data: bytes) -> pathlib.Path | None:
    """The job file named on standard input (see :meth:`Worker.submit`); None: no job."""
    if not data:
        return None
    if not data.endswith(b"\0") or b"\0" in data[:-1]:
        raise ValueError("the job file name handed over is not one NUL-terminated path")
    return pathlib.Path(os.fsdecode(data[:-1]))


def _draw(argv: list[str]) -> dict | None:
    """Warm up, wait for the job, draw it; the reply (None: no job was given)."""
    kind, arg = argv[0], (argv[1] if len(argv) > 1 else "")
    if kind == "plots":
        from app.plot import plots as module
    else:
        from app.plot import screenshots as module
    module.warm_up(arg)
    job_path = _job_path(sys.stdin.buffer.read())
    if job_path is None:        # closed without a job: the study ended without pictures
        return None
    job = json.loads(job_path.read_text())
    t0 = time.perf_counter()
    files, notes = module.draw_job(job)
    return {"files": [str(f) for f in files], "notes": notes, "seconds": time.perf_counter() - t0}


def _main(argv: list[str]) -> int:
    """The child: 0 with the reply on standard output, or 1 with a failure's reply; it never
    prints a traceback (the parent reports the failure, :meth:`Worker.wait`)."""
    # Ctrl-C is for the run: this child ends when the run closes its standard input (or dies)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent()
    # below the study's priority: it warms up while the study runs and must not slow it down
    # (after the study the run only waits for it)
    try:
        os.nice(NICE)
    except OSError:
        pass
    try:
        reply = _draw(argv)
    except BaseException as err:      # noqa: BLE001 - any failure is one reply line for the parent
        reply, code = _failure(err), 1
    else:
        code = 0
    if reply is not None:
        try:
            print(json.dumps(reply), flush=True)
        except OSError:               # the run is gone (its end of the pipe closed)
            return 1
    return code


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))

