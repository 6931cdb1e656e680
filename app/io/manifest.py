"""The marker file of the app's folders and the list of what the app wrote there (its manifest).

Every folder the app writes carries :data:`MARKER` (the app's name, the folder kind, a format
version). When a results folder is complete (app/io/folder.py, a sweep's case), the marker also
lists every sub-folder and regular file in it (:func:`seal`): those are the app's own files, the
only ones ``--overwrite`` and ``render`` ever replace or delete. Anything else under the folder
(a user's file, a symbolic link, a FIFO) is foreign (:func:`foreign_paths`). The marker itself is
read as an untrusted file (app/io/untrusted.py).
"""
from __future__ import annotations

import json
import os
import pathlib
import stat

APP = "contact-divergence"
#: format 2 records every file and sub-folder of a results folder (format 1: its top-level names)
FORMAT_VERSION = 2
MARKER = ".contact-divergence.json"
#: the largest marker read (its file list of a study with many proofs and pictures)
MARKER_MAX_BYTES = 64 * 2**20


def write_marker(folder: pathlib.Path, kind: str, tree: tuple[list[str], list[str]] | None = None) -> None:
    """Mark ``folder`` as written by this app (``kind``: 'results' or 'sweep'). ``tree``: the
    sub-folders and files the app wrote there (:func:`app_tree`), recorded when a results folder
    is complete; only those are ever replaced or deleted later."""
    from app.version import __version__
    data: dict = {"app": APP, "kind": kind, "format": FORMAT_VERSION, "version": __version__}
    if tree is not None:
        folders, files = tree
        data["entries"] = sorted({p.split("/")[0] for p in folders + files})
        data["folders"], data["files"] = sorted(folders), sorted(files)
    from app.io.results import atomic_write
    atomic_write(folder / MARKER, json.dumps(data) + "\n")


def app_tree(folder: pathlib.Path) -> tuple[list[str], list[str]]:
    """(sub-folders, regular files) under ``folder`` as relative POSIX paths, the marker left out;
    symbolic links are not followed and not listed (the app writes none)."""
    folders: list[str] = []
    files: list[str] = []
    for root, dirs, names in os.walk(folder):
        rel = pathlib.Path(root).relative_to(folder)
        for d in list(dirs):
            if os.path.islink(os.path.join(root, d)):
                dirs.remove(d)
            else:
                folders.append((rel / d).as_posix())
        files += [(rel / n).as_posix() for n in names
                  if (root != str(folder) or n != MARKER) and stat.S_ISREG(os.lstat(os.path.join(root, n)).st_mode)]
    return folders, files


def seal(folder: pathlib.Path, kind: str = "results") -> None:
    """Record everything in the freshly written ``folder`` as the app's (its marker's file list)."""
    write_marker(folder, kind, app_tree(folder))


def read_marker(folder: pathlib.Path) -> dict | None:
    """The app's marker in ``folder`` as a dictionary, None when there is none that can be read
    (missing, not a regular file, too large, not JSON, or not this app's)."""
    from app.io.untrusted import UntrustedFile, load_json
    try:
        data = load_json(folder / MARKER, MARKER_MAX_BYTES)
    except (OSError, UntrustedFile):
        return None
    if isinstance(data, dict) and data.get("app") == APP and isinstance(data.get("kind"), str):
        return data
    return None


def marker_kind(folder: pathlib.Path) -> str | None:
    """The kind recorded by the app's marker in ``folder``, or None (no marker, or not ours)."""
    data = read_marker(folder)
    return None if data is None else data["kind"]


def recorded(folder: pathlib.Path) -> tuple[set[str], set[str]] | None:
    """(sub-folders, files) the marker of ``folder`` records as the app's, None when it records
    none (no marker, a sweep folder, a folder of an earlier version) or a list the app never
    writes (a path that is not a plain relative path inside the folder: ``..``, ``/x``, ``a//b``)."""
    data = read_marker(folder) or {}
    folders, files = data.get("folders"), data.get("files")
    if not (isinstance(folders, list) and isinstance(files, list) and all(map(_plain, folders + files))):
        return None
    return set(folders), set(files)


def _plain(path) -> bool:
    """``path`` is a relative POSIX path of plain names (no ``.``, ``..``, empty part or NUL)."""
    return (isinstance(path, str) and bool(path) and "\0" not in path
            and all(part not in ("", ".", "..") for part in path.split("/")))


def foreign_paths(folder: pathlib.Path) -> list[str] | None:
    """Paths under ``folder`` the app did not record writing (sub-folders with a trailing ``/``;
    a symbolic link, a FIFO or a file where the app recorded another kind count as foreign);
    None when the marker records no file list (then nothing there can be told apart)."""
    known = recorded(folder)
    if known is None:
        return None
    folders, files = known
    out: list[str] = []

    def walk(path: pathlib.Path, rel: str) -> None:
        try:
            entries = sorted(os.scandir(path), key=lambda e: e.name)
        except OSError:
            out.append(rel + "/" if rel else "./")
            return
        for e in entries:
            name = f"{rel}/{e.name}" if rel else e.name
            if not rel and e.name == MARKER:
                continue
            if e.is_dir(follow_symlinks=False) and name in folders:
                walk(pathlib.Path(e.path), name)
            elif not (e.is_file(follow_symlinks=False) and name in files):
                out.append(name + "/" if e.is_dir(follow_symlinks=False) else name)

    walk(folder, "")
    return out


def foreign_entries(folder: pathlib.Path) -> list[str]:
    """Paths in a marked folder that the app did not record writing ([] when it records none)."""
    return foreign_paths(folder) or []


def remove_recorded(folder: pathlib.Path) -> bool:
    """Delete what the marker of ``folder`` records as the app's, then the folder if that empties
    it; anything else stays. Never follows a symbolic link. True when the folder is gone."""
    known = recorded(folder)
    if known is not None:
        folders, files = known
        for rel in sorted(files):
            path = folder / rel
            try:
                if stat.S_ISREG(os.lstat(path).st_mode) and _inside(folder, path.parent, folders):
                    os.unlink(path)
            except OSError:
                pass
        for rel in sorted(folders, key=lambda p: -p.count("/")):     # deepest first
            try:
                os.rmdir(folder / rel)
            except OSError:
                pass
    try:
        os.unlink(folder / MARKER)
        os.rmdir(folder)
    except OSError:
        return False
    return True


def _inside(folder: pathlib.Path, parent: pathlib.Path, folders: set[str]) -> bool:
    """``parent`` (a folder under ``folder``) is reached through recorded real folders only."""
    rel = parent.relative_to(folder)
    for k in range(1, len(rel.parts) + 1):
        sub = pathlib.PurePosixPath(*rel.parts[:k]).as_posix()
        if sub not in folders or not stat.S_ISDIR(os.lstat(folder / sub).st_mode):
            return False
    return True


def describe_foreign(folder: pathlib.Path) -> str:
    """Why ``folder`` is not the app's alone, as a parenthesis for an error line."""
    extra = foreign_paths(folder)
    if extra:
        return f" ({', '.join(extra[:3])}{', ...' if len(extra) > 3 else ''} besides this app's results)"
    if extra is None and marker_kind(folder) == "results":
        return (" (its marker has no usable list of its files: written by an earlier version of this app, or changed; "
                "they cannot be told from yours)")
    return " (not results written by this app)"
