"""Reading the files of a results folder, which anyone may have changed since the app wrote them.

A results folder is read again by ``python -m app render`` (and ``--overwrite`` reads its
marker). Nothing there is trusted: a name may be a symbolic link, a FIFO (opening it for reading
would wait forever), a device, or a huge or deeply nested file. Every file is therefore checked
before it is read: ``lstat`` (a regular file, not a link), then ``open`` with ``O_NOFOLLOW`` and
``O_NONBLOCK`` and ``fstat`` on the open file (still a regular file, the same one, not larger
than the caller allows). The ``.npy`` headers of an ``.npz`` archive are checked against the
archive's sizes and the memory limit before any array is allocated.

Each problem is an :class:`UntrustedFile` whose text is one line naming the file.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import os
import pathlib
import stat
import zipfile
from typing import Iterator

import numpy as np

#: the largest results.json read back (the default ``max_states``, 100,000, at 10 kB a state)
RESULTS_MAX_BYTES = 2**30


class UntrustedFile(Exception):
    """A file of a results folder that cannot be used; ``str(err)`` is one line naming it."""


def _size(n: float) -> str:
    """A byte count for people: ``3.0 GiB``, ``12.4 MiB``, ``512 bytes``."""
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{int(n)} bytes"


def kind_of(mode: int) -> str:
    """What a file that is not a regular file is, in words."""
    for test, name in ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def open_regular(path: pathlib.Path, max_bytes: int) -> int:
    """A read-only descriptor of the regular file ``path`` of at most ``max_bytes`` bytes.

    Never follows a symbolic link and never waits on a FIFO or a device: those are refused
    before (``lstat``) and after (``fstat``) the ``open``. Raises :class:`UntrustedFile`
    (FileNotFoundError for a missing file)."""
    try:
        before = os.lstat(path)
    except FileNotFoundError:
        raise
    except OSError as err:
        raise UntrustedFile(f"{path}: cannot be read ({err.strerror or err})") from None
    if not stat.S_ISREG(before.st_mode):
        raise UntrustedFile(f"{path}: is {kind_of(before.st_mode)}, not a regular file: it is not read")
    flags = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as err:
        raise UntrustedFile(f"{path}: cannot be read ({err.strerror or err})") from None
    try:
        now = os.fstat(fd)
        if not stat.S_ISREG(now.st_mode) or not os.path.samestat(before, now):
            raise UntrustedFile(f"{path}: was replaced while it was opened: it is not read")
        if now.st_size > max_bytes:
            raise UntrustedFile(f"{path}: {_size(now.st_size)} ({now.st_size} bytes) is over the "
                                f"{_size(max_bytes)} allowed for this file: it is not read")
    except BaseException:
        os.close(fd)
        raise
    return fd


@contextlib.contextmanager
def opened(path: pathlib.Path, max_bytes: int) -> Iterator[io.BufferedReader]:
    """:func:`open_regular` as a binary file object, closed at the end."""
    with os.fdopen(open_regular(path, max_bytes), "rb") as f:
        yield f


def read_bytes(path: pathlib.Path, max_bytes: int) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_regular`); never more than ``max_bytes``."""
    with opened(path, max_bytes) as f:
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise UntrustedFile(f"{path}: grew over the {_size(max_bytes)} allowed for this file while it was read")
    return data


def parse_json(text: str | bytes, where: str):
    """The JSON value of ``text`` (``where`` names it); malformed or too deeply nested JSON is one line."""
    try:
        return json.loads(text)
    except RecursionError:
        raise UntrustedFile(f"{where}: nested too deeply to be read (not a file this app wrote)") from None
    except ValueError as err:
        raise UntrustedFile(f"{where}: not valid JSON ({err})") from None


def load_json(path: pathlib.Path, max_bytes: int):
    """The JSON value of ``path``; malformed, too large or too deeply nested JSON is one line."""
    return parse_json(read_bytes(path, max_bytes), str(path))


def inside(folder: pathlib.Path, *parts: str) -> pathlib.Path:
    """``folder / parts...`` with every folder on the way checked: a symbolic link or a file there is
    refused (:class:`UntrustedFile`), so nothing reached through the folder leads out of it (the
    folder itself may be a link the user gave). A missing part is not checked: opening the path
    then raises FileNotFoundError."""
    path = pathlib.Path(folder)
    for name in parts:
        if name in ("", ".", "..") or "/" in name:
            raise UntrustedFile(f"{path}: {name!r} is not a plain name")
    for name in parts[:-1]:
        path = path / name
        try:
            mode = os.lstat(path).st_mode
        except FileNotFoundError:
            return pathlib.Path(folder).joinpath(*parts)
        except OSError as err:
            raise UntrustedFile(f"{path}: cannot be read ({err.strerror or err})") from None
        if not stat.S_ISDIR(mode):
            raise UntrustedFile(f"{path}: is {kind_of(mode)}, not a folder: nothing in it is read")
    return path / parts[-1]


def memory_limit() -> float:
    """The memory a results folder's arrays may take: the default of ``settings.limits.max_memory_gb``
    (80 % of the machine's RAM); a limit given in the results is not trusted."""
    from app.systems.schema import Limits
    return Limits().memory_cap()[0]


def _npy_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str) -> tuple[tuple, np.dtype, int]:
    """(shape, dtype, bytes of magic and header) of the ``.npy`` member ``info``, read without its data."""
    fmt = np.lib.format
    with archive.open(info) as member:
        try:
            version = fmt.read_magic(member)
            read_header = {(1, 0): fmt.read_array_header_1_0, (2, 0): fmt.read_array_header_2_0}.get(version)
            if read_header is None:
                raise ValueError(f".npy format version {version}: allowed: 1.0 and 2.0")
            shape, _, dtype = read_header(member)
        except (ValueError, TypeError, SyntaxError, EOFError, OSError) as err:
            raise UntrustedFile(f"{where}: {info.filename}: not a readable .npy header ({err})") from None
        return shape, dtype, member.tell()


def _npy_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str) -> int:
    """The data bytes the ``.npy`` member ``info`` declares, checked against its size in the archive."""
    shape, dtype, header_end = _npy_header(archive, info, where)
    if dtype.hasobject:
        raise UntrustedFile(f"{where}: {info.filename}: holds Python objects ({dtype}): only numbers and text are read")
    count = math.prod(int(n) for n in shape)
    declared = count * dtype.itemsize
    if declared != info.file_size - header_end:
        raise UntrustedFile(f"{where}: {info.filename}: its header declares shape {tuple(shape)} of {dtype} "
                            f"({_size(declared)}) but the member holds {_size(max(0, info.file_size - header_end))}")
    return declared


def check_npz(f: io.BufferedReader, where: str, memory: float | None = None) -> None:
    """Check every ``.npy`` header of the ``.npz`` archive ``f`` before any array is read: each
    declares exactly the data its member holds, and all of them together fit in ``memory`` bytes
    (default :func:`memory_limit`). ``where`` names the file in the error line."""
    memory = memory_limit() if memory is None else memory
    try:
        archive = zipfile.ZipFile(f)
    except (zipfile.BadZipFile, OSError, ValueError) as err:
        raise UntrustedFile(f"{where}: not an .npz archive ({err})") from None
    total = 0
    with archive:
        for info in archive.infolist():
            if info.filename.endswith(".npy"):
                total += _npy_member(archive, info, where)
    if total > memory:
        raise UntrustedFile(f"{where}: its arrays need {_size(total)} of memory, over the limit of {_size(memory)} "
                            f"(80 % of this machine's RAM)")
    f.seek(0)


def read_npz(path: pathlib.Path, members: dict[str, tuple[str, int]], optional: frozenset[str] = frozenset(),
             max_side: int | None = None, memory: float | None = None,
             max_text: int = 2**28) -> dict[str, np.ndarray]:
    """The arrays ``members`` (name -> (dtype kind, number of dimensions): ``("f", 2)`` a float64
    matrix, ``("U", 0)`` a text of at most ``max_text`` characters) of the ``.npz`` file ``path``;
    those in ``optional`` may be absent. Every header is checked first (:func:`check_npz`:
    declared sizes, objects, memory), then each member's dtype, dimensions and sides (at most
    ``max_side``), before any array is read."""
    with opened(path, int(min(memory_limit() if memory is None else memory, 2**62))) as f:
        check_npz(f, str(path), memory)
        try:
            archive = zipfile.ZipFile(f)
        except (zipfile.BadZipFile, OSError, ValueError) as err:
            raise UntrustedFile(f"{path}: not an .npz archive ({err})") from None
        out = {}
        with archive:
            names = set(archive.namelist())
            for name, (kind, ndim) in members.items():
                if f"{name}.npy" not in names:
                    if name in optional:
                        continue
                    raise UntrustedFile(f"{path}: no array {name!r}")
                shape, dtype, _ = _npy_header(archive, archive.getinfo(f"{name}.npy"), str(path))
                if dtype.kind != kind or (kind == "f" and dtype.itemsize != 8) or len(shape) != ndim \
                        or (max_side is not None and any(n > max_side for n in shape)) \
                        or (kind == "U" and dtype.itemsize > 4 * max_text):
                    want = ("a float64" if kind == "f" else "a text") + f" array of {ndim} dimension(s)"
                    raise UntrustedFile(f"{path}: {name}.npy is {dtype} of shape {tuple(shape)}, expected {want}"
                                        + (f" with sides of at most {max_side}" if max_side is not None else ""))
                with archive.open(f"{name}.npy") as member:
                    out[name] = np.lib.format.read_array(member, allow_pickle=False)
        return out
