"""User-facing failures shared by the modules behind ``python -m app`` (app/cli/main.py, app/study/driver.py,
app/study/sweep.py, app/study/refinement.py): one ``error:`` line on rank 0 and an exit status, so that none of
them imports the CLI module.

Exit status: 0 ok, 2 a user mistake, 3 the study ran but some states failed, 4 the results could
not be written.
"""
from __future__ import annotations

import errno
import sys

EXIT_OK, EXIT_USER, EXIT_INCOMPLETE, EXIT_WRITE = 0, 2, 3, 4

#: what a write fails with when a limit of the file system or of the process is reached: a full
#: disk, a quota, the file-size limit (``ulimit -f``: Python ignores SIGXFSZ, so the write fails)
WRITE_LIMIT_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def write_limit(err: BaseException) -> int | None:
    """The errno of a write that hit a limit (:data:`WRITE_LIMIT_ERRNOS`), however the library
    reports it (an OSError's errno, or h5py/HDF5's or meshio's text); None for any other error."""
    if isinstance(err, OSError) and err.errno in WRITE_LIMIT_ERRNOS:
        return err.errno
    if isinstance(err, (OSError, RuntimeError)):
        text = str(err).lower()
        for code, words in ((errno.ENOSPC, "no space left"), (errno.EDQUOT, "disk quota"),
                            (errno.EFBIG, "file too large")):
            if words in text:
                return code
    return None


def write_limit_text(err: BaseException) -> str:
    """The one-line message for a write that hit a limit (:func:`write_limit`)."""
    where = getattr(err, "filename", None)
    writing = f" (writing {where})" if where else ""
    if write_limit(err) == errno.EFBIG:
        import resource
        soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        limit = "" if soft == resource.RLIM_INFINITY else f" ({soft / 2**20:.4g} MiB)"
        return (f"a file reached the file-size limit of this process{limit}{writing} (ulimit -f): the results "
                "were not written; raise the limit or ask for fewer outputs")
    return f"no space left on the device{writing}: the results were not written"


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
