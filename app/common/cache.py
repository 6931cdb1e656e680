"""The user's cache folders: the block meshes (app/systems/block/mesh.py) and DOLFINx's compiled
forms (app/systems/jit.py).

A cache lives in ``$XDG_CACHE_HOME`` (an absolute path; a relative one is ignored, as the XDG
base directory specification says), else in ``$HOME/.cache``. When that folder cannot be used
(``XDG_CACHE_HOME`` names a file, ``HOME`` is missing or read-only, as for some service
accounts and batch jobs), the cache goes to a folder of this user's own in the temporary folder,
``$TMPDIR/contact-divergence-cache-UID`` (created with mode 0700; used only if it belongs to
this user and nobody else can write to it), and a warning names the variable to set. When that
fails too, :class:`CacheUnusable` is one line naming the variable.
"""
from __future__ import annotations

import functools
import logging
import os
import pathlib
import stat
import tempfile

log = logging.getLogger(__name__)

APP_NAME = "contact-divergence"


class CacheUnusable(Exception):
    """No cache folder can be written: ``str(err)`` is one line naming the variable to set."""


def usable_dir(folder: pathlib.Path) -> str | None:
    """None if ``folder`` exists (or can be created) and a file can be created in it, else why not."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".probe-", suffix=".tmp")
        os.close(fd)
        os.unlink(probe)
        return None
    except OSError as err:
        return err.strerror or type(err).__name__


def user_cache_home() -> tuple[pathlib.Path | None, str]:
    """(the user's cache folder, the variable that names it): ``$XDG_CACHE_HOME`` if absolute,
    else ``$HOME/.cache`` (None when no absolute home folder is known)."""
    base = os.environ.get("XDG_CACHE_HOME")
    if base and os.path.isabs(base):
        return pathlib.Path(base), "XDG_CACHE_HOME"
    home = os.path.expanduser("~")
    return (pathlib.Path(home) / ".cache" if os.path.isabs(home) else None), "HOME"


def _private_temp_dir() -> tuple[pathlib.Path | None, str | None]:
    """(the folder of this user in the temporary folder, or None; why not)."""
    try:
        folder = pathlib.Path(tempfile.gettempdir()) / f"{APP_NAME}-cache-{os.getuid()}"
    except OSError as err:                   # no usable temporary folder at all
        return None, err.strerror or str(err)
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        st = os.lstat(folder)
    except OSError as err:
        return None, f"{folder}: {err.strerror or err}"
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o022:
        return None, f"{folder} is not a folder of this user's own that only this user can write to"
    return folder, None


@functools.lru_cache(maxsize=None)
def _resolve(sub: str, xdg: str | None, home: str | None, tmpdir: str | None) -> pathlib.Path:
    """:func:`cache_dir` for one set of the variables it depends on (so its warning is given once)."""
    primary, variable = user_cache_home()
    why = "no absolute home folder" if primary is None else usable_dir(primary / sub)
    if why is None:
        return primary / sub
    where = f"{variable} = {os.environ.get(variable)!r}"
    fallback, why_not = _private_temp_dir()
    if fallback is not None and (why_not := usable_dir(fallback / sub)) is None:
        _warn_once(where, _why_not(primary), fallback)
        return fallback / sub
    raise CacheUnusable(f"{where}: cannot create the cache folder {primary / sub if primary else '~/.cache'} "
                        f"({why}), nor one in the temporary folder ({why_not}); set XDG_CACHE_HOME to a "
                        f"writable folder")


def _why_not(folder: pathlib.Path | None) -> str:
    """Why the cache folder ``folder`` (None: no home folder) cannot be used, in a few words."""
    if folder is None:
        return "no absolute home folder"
    if folder.exists() and not folder.is_dir():
        return "not a folder"
    return usable_dir(folder) or "its subfolders cannot be written"


@functools.lru_cache(maxsize=None)
def _warn_once(where: str, why: str, fallback: pathlib.Path) -> None:
    """The warning that the caches go to ``fallback`` (once for all the caches of a run)."""
    log.warning("cache: cannot write in the cache folder of %s (%s): the caches go to %s; set XDG_CACHE_HOME "
                "to a writable folder to keep them", where, why, fallback)


def cache_dir(sub: str) -> pathlib.Path:
    """A writable cache folder ``sub`` (e.g. ``"fenics"``) in the user's cache folder, else in this
    user's folder in the temporary folder (a warning, once); raises :class:`CacheUnusable`."""
    env = os.environ
    return _resolve(sub, env.get("XDG_CACHE_HOME"), env.get("HOME"), env.get("TMPDIR"))
