"""Run Gmsh on a user's file in a separate, limited process (app/systems/gmsh/child.py).

A Gmsh file is untrusted: a ``.geo`` is a program (app/systems/gmsh/geo_allowlist.py refuses the
dangerous commands first), and a corrupt ``.msh`` can crash Gmsh (segfaults seen on mutated
node tags). So Gmsh never runs in the app's process. The child

* runs under a time limit (``settings.limits.max_file_seconds``, wall clock; the process group
  is killed at the limit), an address-space limit (``RLIMIT_AS``: the scene's memory limit,
  ``settings.limits.max_memory_gb`` or 80 % of the RAM) and node/element limits derived from
  ``settings.limits.max_dofs``, with no core files and a bounded file size; each limit at most
  the one this process inherited (a batch job's ``ulimit -v``, ``ulimit -f``: a lower inherited
  limit is kept and a warning says so, app/common/rlimits.py);
* has HOME, TMPDIR and its working folder in a fresh temporary folder, created by this module
  and removed by it afterwards, and a minimal environment;
* runs inside bubblewrap (``bwrap``, Debian package ``bubblewrap``, installed by
  scripts/setup.sh) when it works on this machine: the whole file system read-only except the
  temporary folder, no network, its own process namespace, killed with its parent. When bwrap
  is missing or cannot create namespaces (some containers), the plain limits above still apply
  and a note is logged once.

Any crash, timeout or limit becomes one :class:`SandboxError` line; ``resource`` tells the
resource limits (exit status 4) from a bad file (exit status 2).
"""
from __future__ import annotations

import json
import logging
import os
import pathlib
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass

import numpy as np

from app.common.rlimits import INFINITY, Limit, setter, within_inherited

log = logging.getLogger(__name__)

CHILD = pathlib.Path(__file__).with_name("child.py")
#: address space Python, numpy and Gmsh's libraries map before reading anything
BASE_ADDRESS_SPACE = 1 << 30
_BWRAP: dict[str, bool] = {}      # "usable": probed once per process


class SandboxError(Exception):
    """Gmsh could not read the file within the limits: ``str(err)`` is one line."""

    def __init__(self, msg: str, resource: bool = False):
        super().__init__(msg)
        self.resource = resource


@dataclass(frozen=True)
class SandboxLimits:
    """Limits of one child (see the module docstring)."""

    seconds: float
    memory_bytes: int | None
    max_nodes: int
    max_elements: int
    max_dofs: int           # settings.limits.max_dofs, named in the messages

    @classmethod
    def from_limits(cls, limits) -> "SandboxLimits":
        """From a scene's ``settings.limits`` (app/scene/sections.py ``Limits``)."""
        mem, _ = limits.memory_cap()
        # P1: 2 DOFs per node, about 2 triangles per node; P2 has about 4x the DOFs of P1 on the
        # same triangles, so the P1 counts bound both (the exact DOFs are checked by the pre-flight)
        return cls(seconds=float(limits.max_file_seconds), memory_bytes=None if mem == float("inf") else int(mem),
                   max_nodes=max(limits.max_dofs // 2, 3), max_elements=max(limits.max_dofs, 1),
                   max_dofs=limits.max_dofs)


def _bwrap_command(tmp: pathlib.Path) -> list[str]:
    return ["bwrap", "--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc",
            "--bind", str(tmp), str(tmp), "--unshare-all", "--die-with-parent", "--new-session",
            "--chdir", str(tmp), "--setenv", "HOME", str(tmp), "--setenv", "TMPDIR", str(tmp)]


def bwrap_usable() -> bool:
    """Whether bubblewrap can start a sandboxed process here (probed once; a note logged if not)."""
    if "usable" not in _BWRAP:
        ok, why = False, "bwrap is not installed (Debian package bubblewrap, scripts/setup.sh)"
        if shutil.which("bwrap"):
            tmp = pathlib.Path(tempfile.mkdtemp(prefix="app-bwrap-probe-"))
            try:
                r = subprocess.run(_bwrap_command(tmp) + ["/bin/true"], stdin=subprocess.DEVNULL,
                                   capture_output=True, timeout=20)
                ok = r.returncode == 0
                why = " ".join(r.stderr.decode(errors="replace").split())[:200] or f"exit status {r.returncode}"
            except (OSError, subprocess.SubprocessError) as err:
                why = str(err)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
        if not ok:
            log.warning("gmsh sandbox: bubblewrap is not usable (%s): Gmsh runs with time and memory limits "
                        "only, with write access where this process has it", why)
        _BWRAP["usable"] = ok
    return _BWRAP["usable"]


def child_limits(limits: SandboxLimits, file_bytes: int, current=resource.getrlimit,
                 ) -> tuple[dict[int, Limit], list[str]]:
    """The child's resource limits and notes on those the inherited limits keep lower
    (app/common/rlimits.py: a limit is never raised above this process's own, ``current``, e.g.
    a batch job's ``ulimit -v``)."""
    cpu = int(limits.seconds) + 2
    wanted = {resource.RLIMIT_CORE: Limit(0, 0), resource.RLIMIT_FSIZE: Limit(file_bytes, file_bytes),
              resource.RLIMIT_CPU: Limit(cpu, cpu + 1)}
    cap = INFINITY if limits.memory_bytes is None else limits.memory_bytes + BASE_ADDRESS_SPACE
    wanted[resource.RLIMIT_AS] = Limit(cap, cap)
    return within_inherited(wanted, current)


def _signal_name(code: int) -> str:
    try:
        return signal.Signals(-code).name
    except ValueError:
        return f"signal {-code}"


def read(path: pathlib.Path, limits: SandboxLimits, size_factor: float = 1.0) -> tuple[dict, dict]:
    """``(info, arrays)`` of a Gmsh file read by the sandboxed child (a ``.geo`` meshed with its
    characteristic lengths times ``size_factor``); raises :class:`SandboxError`."""
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="app-gmsh-"))
    try:
        return _run(path, limits, tmp, size_factor)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)        # the folder this call created, with what the child wrote


def _run(path: pathlib.Path, limits: SandboxLimits, tmp: pathlib.Path, size_factor: float) -> tuple[dict, dict]:
    name = path.name
    # bytes the child may write: the arrays (about 100 bytes per element) and gmsh's messages
    file_bytes = 64 * 2**20 + 200 * (limits.max_elements + limits.max_nodes)
    cmd = [sys.executable, "-I", str(CHILD), str(path), str(tmp), str(limits.max_nodes), str(limits.max_elements),
           str(limits.max_dofs), repr(float(size_factor))]
    if bwrap_usable():
        cmd = _bwrap_command(tmp) + ["--"] + cmd
    rlimits, notes = child_limits(limits, file_bytes)
    if notes:
        log.warning("gmsh sandbox: reading %s with lower limits than the app sets, as this process's own are "
                    "lower: %s", name, "; ".join(notes))
    env = {"HOME": str(tmp), "TMPDIR": str(tmp), "PATH": "/usr/bin:/bin", "LANG": "C.UTF-8",
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    with open(tmp / "stderr.txt", "wb") as err_file:
        try:
            proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err_file,
                                    cwd=tmp, env=env, start_new_session=True,
                                    preexec_fn=setter(rlimits))
        except OSError as err:
            raise SandboxError(f"cannot start the process that reads {name}: {err.strerror or err}") from None
        try:
            code = proc.wait(timeout=limits.seconds)
        except subprocess.TimeoutExpired:
            _kill(proc)
            raise SandboxError(f"reading {name} with gmsh took more than settings.limits.max_file_seconds = "
                               f"{limits.seconds:g} s: stopped (a mesh too fine, or a script that does not end)",
                               resource=True) from None
        except BaseException:
            _kill(proc)
            raise
    stderr = (tmp / "stderr.txt").read_bytes()[-4000:].decode(errors="replace")
    info_file = tmp / "info.json"
    if code == 0 or (info_file.exists() and code > 0):
        try:
            info = json.loads(info_file.read_text())
        except (OSError, ValueError):
            info = None
        if isinstance(info, dict) and "error" in info:
            raise SandboxError(str(info["error"]))
        if code == 0 and isinstance(info, dict):
            with np.load(tmp / "arrays.npz", allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
            return info, arrays
    if "MemoryError" in stderr or "bad_alloc" in stderr or (code < 0 and -code in (signal.SIGXCPU,)):
        what = ("memory" if code >= 0 or -code != signal.SIGXCPU else "CPU time")
        raise SandboxError(f"reading {name} with gmsh ran out of its {what} limit "
                           f"({_memory_text(limits, rlimits)}): use a coarser mesh or raise settings.limits.max_memory_gb",
                           resource=True)
    if code < 0 and -code == signal.SIGXFSZ:
        written = rlimits[resource.RLIMIT_FSIZE].soft
        raise SandboxError(f"reading {name} with gmsh wrote more than {written >> 20} MiB: stopped", resource=True)
    if code < 0:
        raise SandboxError(f"gmsh crashed reading {name} ({_signal_name(code)}): the file is corrupt or not a "
                           "mesh gmsh can read")
    last = " ".join(stderr.strip().splitlines()[-1:]).strip()[:160] if stderr.strip() else ""
    raise SandboxError(f"gmsh failed reading {name} (exit status {code}{': ' + last if last else ''})")


def _memory_text(limits: SandboxLimits, rlimits: dict[int, Limit]) -> str:
    """The child's memory limit as the messages name it: the scene's, or the inherited address-space
    limit where that is lower."""
    soft = rlimits[resource.RLIMIT_AS].soft
    if soft == INFINITY:
        return "no memory limit"
    if limits.memory_bytes is None or soft < limits.memory_bytes + BASE_ADDRESS_SPACE:
        return f"the address-space limit (ulimit -v) of {soft / 2**30:.3g} GiB"
    return f"{limits.memory_bytes / 2**30:.3g} GiB"


def _kill(proc: subprocess.Popen) -> None:
    """Kill the child's process group (the child and anything it started) and reap it."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass
