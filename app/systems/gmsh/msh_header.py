"""Check a ``.msh`` file's headers before Gmsh reads it (without reading the mesh itself).

Gmsh reads a file that does not start with ``$MeshFormat`` as a ``.geo`` script, whatever its
name, so such a file is refused here. The ``$Nodes`` and ``$Elements`` headers (MSH 2.x ASCII
or binary, MSH 4.x ASCII or binary) give the counts, checked against the limits before any
array is allocated; node and element tags far beyond the counts are refused (Gmsh 4.8 sizes
arrays by the largest tag: a tag of 1e15 crashed it). The file is then read by Gmsh in the
sandbox (app/systems/gmsh/sandbox.py), which also bounds what a corrupt body does.
"""
from __future__ import annotations

import mmap
import pathlib
import struct
from dataclasses import dataclass

MAX_TAG = 10**9                     # larger node or element tags are refused


class MshRefused(ValueError):
    """A .msh file refused from its headers: ``str(err)`` is one line."""


@dataclass(frozen=True)
class MshHeader:
    """What a .msh file's headers say: the format version, whether it is binary, and the node and
    element counts (None where the section is missing)."""

    version: str
    binary: bool
    nodes: int | None           # None: no $Nodes section found (Gmsh reports it)
    elements: int | None


def _ascii_numbers(buf: mmap.mmap, start: int, count: int, name: str, section: str) -> list[int]:
    end = buf.find(b"\n", start, start + 4096)
    if end < 0:
        raise MshRefused(f"{name}: the {section} header line is missing or too long")
    try:
        values = [int(v) for v in bytes(buf[start:end]).split()[:count]]
    except ValueError:
        raise MshRefused(f"{name}: the {section} header is not a list of integers") from None
    if len(values) < count:
        raise MshRefused(f"{name}: the {section} header has {len(values)} numbers, {count} expected")
    return values


def _section(buf: mmap.mmap, tag: bytes) -> int:
    """Offset of the first byte after the line ``tag`` (-1 if absent)."""
    at = buf.find(b"\n" + tag)
    if at < 0:
        return -1
    end = buf.find(b"\n", at + 1)
    return -1 if end < 0 else end + 1


def read_header(path: pathlib.Path, name: str) -> MshHeader:
    """The version and counts of ``path``; raises :class:`MshRefused` for a file that is no MSH file."""
    with open(path, "rb") as f:
        head = f.read(64)
        if not head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"$MeshFormat"):
            raise MshRefused(f"{name} does not start with $MeshFormat: not a Gmsh mesh file (Gmsh would run it as "
                             "a script; give a .geo for a script)")
        try:
            buf = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except (ValueError, OSError) as err:
            raise MshRefused(f"cannot read {name}: {err}") from None
    with buf:
        start = buf.find(b"$MeshFormat") + len(b"$MeshFormat")
        line_end = buf.find(b"\n", start + 1, start + 200)
        fmt = bytes(buf[start:line_end if line_end > 0 else start + 200]).split()
        if len(fmt) < 3:
            raise MshRefused(f"{name}: the $MeshFormat line must give version, file type and data size")
        version, ftype, dsize = (v.decode("ascii", "replace") for v in fmt[:3])
        if version not in ("2", "2.0", "2.1", "2.2", "4", "4.0", "4.1") or ftype not in ("0", "1") or dsize != "8":
            raise MshRefused(f"{name}: MSH format '{version} {ftype} {dsize}' is not supported (MSH 2.2 or 4.1, "
                             "data size 8)")
        binary, v4 = ftype == "1", version.startswith("4")
        counts = []
        for section in (b"$Nodes", b"$Elements"):
            at = _section(buf, section)
            if at < 0:
                counts.append(None)
                continue
            label = section.decode()
            if v4 and binary:
                raw = bytes(buf[at:at + 32])
                if len(raw) < 32:
                    raise MshRefused(f"{name}: the {label} header is cut off")
                _, number, _, max_tag = struct.unpack("<4Q", raw)
            elif v4:
                n = 4 if version == "4.1" else 2
                values = _ascii_numbers(buf, at, n, name, label)
                number, max_tag = values[1], (values[3] if n == 4 else values[1])
            else:
                number = _ascii_numbers(buf, at, 1, name, label)[0]
                max_tag = number
            if number < 0 or max_tag < 0:
                raise MshRefused(f"{name}: the {label} header gives a negative count")
            if v4 and (max_tag > MAX_TAG or max_tag > 1000 * number + 10**6):
                raise MshRefused(f"{name}: the {label} header declares tags up to {max_tag} for {number} entries: "
                                 f"at most {MAX_TAG} and not far beyond the count (renumber the mesh)")
            counts.append(number)
    return MshHeader(version=version, binary=binary, nodes=counts[0], elements=counts[1])


def check(path: pathlib.Path, name: str, max_nodes: int, max_elements: int, max_dofs: int) -> MshHeader:
    """:func:`read_header` and the counts against the limits (raises :class:`MshRefused`)."""
    h = read_header(path, name)
    if h.nodes is not None and h.nodes > max_nodes:
        raise MshRefused(f"{name} declares {h.nodes} nodes (2 DOFs each), above the {max_nodes} that "
                         f"settings.limits.max_dofs = {max_dofs} allows; use a coarser mesh or raise the limit")
    # elements of every dimension: triangles, and the lines and points of the physical groups
    if h.elements is not None and h.elements > 2 * max_elements + 10**5:
        raise MshRefused(f"{name} declares {h.elements} elements, above the {2 * max_elements + 10**5} that "
                         f"settings.limits.max_dofs = {max_dofs} allows; use a coarser mesh or raise the limit")
    return h
