"""A results folder that never looks complete when it is not, and never replaces what the app did not write.

A run writes into a hidden staging folder beside the target (``.NAME.partial-PID-TIME``) and
moves it into place only when everything is written. The app marks every folder it writes with
a small file (:data:`MARKER`: the app's name, the folder kind, a format version and, once a
results folder is complete, the list of every sub-folder and file the app wrote there). An
existing target is replaced (``--overwrite``) only when it is empty or carries that marker and
holds nothing else; a folder holding anything else is refused, and nothing in it is touched.
The previous results are then deleted file by file from that list (:func:`remove_recorded`),
never by removing a whole tree.

Everything the final rename needs is checked before the work starts (the target is not ``.``,
not a mount point, its parent is writable, a folder can be created and renamed there, the
sticky-bit rule allows replacing it). A lock file beside the target (``.NAME.lock``, ``flock``)
refuses a second concurrent run. If the final rename still fails, the staged results are kept
and the error says where they are. An interrupted run leaves the previous results untouched
(a SIGKILL leaves the ``.partial`` folder behind).
"""
from __future__ import annotations

import errno
import fcntl
import logging
import os
import pathlib
import shutil
import stat
import time

from app.io.manifest import (  # noqa: F401 - re-exported: the marker is part of a results folder
    APP,
    FORMAT_VERSION,
    MARKER,
    describe_foreign,
    foreign_entries,
    foreign_paths,
    marker_kind,
    recorded,
    remove_recorded,
    seal,
    write_marker,
)

log = logging.getLogger(__name__)

class CommitError(Exception):
    """The final rename failed; ``str(err)`` is one line saying where the results were kept."""


def folder_state(folder: pathlib.Path) -> str:
    """'missing', 'empty', 'ours' (carries the marker and nothing the app did not record writing),
    'other' (anything else) or 'not-a-folder'."""
    if not folder.exists() and not folder.is_symlink():
        return "missing"
    if folder.is_symlink() or not folder.is_dir():
        return "not-a-folder"
    try:
        if not any(folder.iterdir()):
            return "empty"
    except OSError:
        return "other"
    kind = marker_kind(folder)
    if kind is None or (kind == "results" and foreign_paths(folder) != []):
        return "other"
    return "ours"


def _is_cwd_or_ancestor(path: pathlib.Path) -> bool:
    try:
        target = path.resolve()
        cwd = pathlib.Path.cwd().resolve()
    except OSError:
        return False
    return target == cwd or target in cwd.parents


def _sticky_blocks(parent: pathlib.Path, target: pathlib.Path) -> bool:
    """The sticky bit of ``parent`` (as on /tmp) forbids replacing ``target``, owned by someone else."""
    if os.geteuid() == 0:
        return False
    try:
        pst, tst = parent.stat(), target.stat()
    except OSError:
        return False
    me = os.geteuid()
    return bool(pst.st_mode & stat.S_ISVTX) and tst.st_uid != me and pst.st_uid != me


def folder_of(lock_path: pathlib.Path) -> pathlib.Path:
    """The folder a lock file ``.NAME.lock`` belongs to."""
    return lock_path.parent / lock_path.name[1:-len(".lock")]


class FolderLock:
    """An exclusive ``flock`` on ``.NAME.lock`` beside a folder (refuses a second concurrent run).

    The lock file is removed at the end only by the run that created it: a file of that name
    that was already there (a user's own, or one left by a killed run) is locked but kept.

    ``fcntl.flock`` directly rather than the filelock package: the kernel releases the lock when
    the process dies, even by SIGKILL, and filelock's Unix lock is that same call with thread
    re-entrancy and a timeout loop the app does not need; what it cannot give is the rule above
    (never delete a lock file the run did not create), which is the part written here."""

    def __init__(self, folder: pathlib.Path):
        self.path = folder.parent / f".{folder.name}.lock"
        self._fd: int | None = None
        self._created = False

    def _open(self) -> tuple[int | None, bool, str | None]:
        """(fd, created by this call, problem): create the lock file, or open the one already there."""
        cloexec = getattr(os, "O_CLOEXEC", 0)
        try:
            return os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL | cloexec, 0o666), True, None
        except FileExistsError:
            pass
        except OSError as err:
            return None, False, (f"cannot write the output folder {folder_of(self.path)}: cannot create the lock "
                                 f"file {self.path}: {err.strerror or err}")
        try:       # read-only, non-blocking: never written, and a FIFO of that name cannot hang the run
            return os.open(self.path, os.O_RDONLY | os.O_NONBLOCK | cloexec), False, None
        except FileNotFoundError:                # removed meanwhile by a finishing run: try again
            return None, False, None
        except OSError as err:
            return None, False, f"cannot open the lock file {self.path}: {err.strerror or err}"

    def acquire(self) -> str | None:
        """None on success, else the one-line problem."""
        for _ in range(3):
            fd, created, problem = self._open()
            if problem is not None:
                return problem
            if fd is None:
                continue
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as err:
                os.close(fd)       # (a file this call created is kept: the run holding it now owns it)
                if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    return (f"another run is writing to {folder_of(self.path)} (lock {self.path} "
                            f"is held): wait for it to finish or choose another folder with -o")
                return f"cannot lock {self.path}: {err.strerror or err}"
            try:   # the file we locked must still be the one at the path (a finished run unlinks it)
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except OSError:
                same = False
            if same:
                self._fd, self._created = fd, created
                return None
            os.close(fd)
        return f"cannot lock {self.path}: it keeps being replaced"

    def release(self) -> None:
        """Unlock: close the lock file, and remove it first if this run created it (a no-op when not
        held)."""
        fd, self._fd = self._fd, None
        if fd is not None:
            if self._created:
                try:
                    os.unlink(self.path)
                except OSError:
                    pass
            try:
                os.close(fd)
            except OSError:       # closed already (a hard stop's cleanup in another thread)
                pass


class ResultsFolder:
    """Staging and atomic replacement of a results folder (used on rank 0 only)."""

    kind = "results"

    def __init__(self, final: pathlib.Path, overwrite: bool):
        self.final = pathlib.Path(final)
        self.overwrite = overwrite
        tag = f"{os.getpid()}-{int(time.time())}"
        self.staging = self.final.parent / f".{self.final.name}.partial-{tag}"
        self._old = self.final.parent / f".{self.final.name}.old-{tag}"
        self.lock = FolderLock(self.final)
        self._opened = False
        self._kept = False

    def check(self) -> str | None:
        """Pre-flight everything the final commit needs; a one-line problem, or None.

        On success the lock is held and the staging folder exists (empty but for the marker).
        """
        problem = self._check_target()
        if problem is None:
            problem = self.lock.acquire()
            if problem is None:
                problem = self._check_target() or self._probe_staging()   # again, now that we hold the lock
                if problem is not None:
                    self.lock.release()
        return problem

    def _check_target(self) -> str | None:
        final = self.final
        if final.name in ("", ".", "..") or _is_cwd_or_ancestor(final):
            return (f"the output folder {final} is the current folder (or holds it): it cannot be replaced "
                    f"by the results; choose a new folder with -o")
        state = folder_state(final)
        if state == "not-a-folder":
            return f"cannot create the output folder {final}: a file of that name exists"
        if state == "other":
            return (f"the output folder {final} holds other files{describe_foreign(final)}: "
                    f"nothing was changed; choose a new or empty folder with -o"
                    + (" (--overwrite only replaces results this app wrote)" if self.overwrite else ""))
        if state == "ours" and marker_kind(final) != self.kind:
            return (f"the output folder {final} holds a {marker_kind(final)} folder of this app, not the results "
                    f"of a single study: nothing was changed; choose another folder with -o")
        if state == "ours" and not self.overwrite:
            return (f"the output folder {final} already holds results of this app; "
                    f"use --overwrite to replace them, or choose another folder with -o")
        if state in ("ours", "empty") and os.path.ismount(final):
            return f"the output folder {final} is a mount point: it cannot be replaced; choose a folder inside it"
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            return f"cannot create the output folder {final}: {err.strerror or err}"
        if not final.parent.is_dir():
            return f"cannot create the output folder {final}: {final.parent} is not a folder"
        if not os.access(final.parent, os.W_OK | os.X_OK):
            return f"the output folder {final} cannot be written (its parent {final.parent} is not writable)"
        if state in ("ours", "empty") and _sticky_blocks(final.parent, final):
            return (f"the output folder {final} belongs to another user in a sticky folder ({final.parent}): "
                    f"it cannot be replaced; choose another folder with -o")
        return None

    def _probe_staging(self) -> str | None:
        """Create the staging folder and rename it once: the final rename works the same way."""
        probe = self.staging.with_name(self.staging.name + "-probe")
        made = None            # the one path this run created (only that is removed on failure)
        try:
            self.staging.mkdir(parents=False, exist_ok=False)
            made = self.staging
            os.rename(self.staging, probe)     # refuses a non-empty existing probe: nothing is replaced
            made = probe
            os.rename(probe, self.staging)
            made = self.staging
            write_marker(self.staging, self.kind)
        except OSError as err:
            if made is not None and made.is_dir() and not made.is_symlink():
                shutil.rmtree(made, ignore_errors=True)
            return f"cannot write the output folder {self.final}: {err.strerror or err} ({err.filename or self.final.parent})"
        self._opened = True
        return None

    def open(self) -> pathlib.Path:
        """The staging folder (created by :meth:`check`)."""
        if not self._opened:
            problem = self.check()
            if problem:
                raise CommitError(problem)
        return self.staging

    def commit(self) -> pathlib.Path:
        """Move the staged results into place. The target is checked again: if it now holds other
        files, or a rename fails, the staged results stay where they are (:class:`CommitError`)."""
        state = folder_state(self.final)
        try:
            seal(self.staging, self.kind)      # what the app wrote: only that is replaced or deleted later
            if state == "other" or state == "not-a-folder":
                raise CommitError(f"the output folder {self.final} now holds other files")
            if state == "ours":
                os.rename(self.final, self._old)
            try:
                os.rename(self.staging, self.final)      # atomic; replaces an empty folder
            except OSError:
                if state == "ours" and self._old.exists() and not self.final.exists():
                    os.rename(self._old, self.final)     # put the previous results back
                raise
        except (OSError, CommitError) as err:
            why = err.strerror if isinstance(err, OSError) and err.strerror else str(err)
            self.lock.release()
            self._kept = True
            raise CommitError(f"could not move the results into {self.final} ({why}); "
                              f"the complete results are kept in {self.staging}") from None
        if state == "ours" and not remove_recorded(self._old):
            log.warning("kept %s: it holds files this app did not write", self._old)
        self.lock.release()
        return self.final

    def abort(self) -> None:
        """Drop the staging folder (only the one this run created) and the lock."""
        if self._opened and not self._kept and self.staging.is_dir() and not self.staging.is_symlink():
            shutil.rmtree(self.staging, ignore_errors=True)
        self.lock.release()
