"""The ``results.json`` document: a study's results dictionary as JSON data and back.

:func:`to_document` writes it (numbers that are not finite become ``null``, listed in the
``non_finite`` block), :func:`from_document` reads a document of any format version back into a
results dictionary (infinities as floats again). This module imports neither PETSc nor DOLFINx.
"""
from __future__ import annotations

import json
import math
from typing import Any, Mapping

import numpy as np

#: version of the results.json format, written as its ``format_version`` key (1: non-finite
#: numbers written as the strings ``"inf"``/``"-inf"``; 2: written as ``null``, each listed with
#: its value under the top-level key ``non_finite``; 3: no unit in a key name, the units are the
#: top-level ``units`` block's, see :data:`RENAMED`). :func:`from_document` reads all three.
FORMAT_VERSION = 3

#: keys of ``path`` renamed in format 3 (old name -> new name): the unit left the name for the
#: ``units`` block (it said "mm" and "N" whatever the scene's units were)
RENAMED = {"path": {"normal_displacement_mm": "normal_displacement", "normal_force_N": "normal_force",
                    "tangential_step_mm": "tangential_step"}}

#: why a number of results.json is ``null`` (the ``non_finite`` block says which and what it is)
NON_FINITE_REASON = ("JSON has no infinity or NaN: these numbers are written as null; 'values' maps the "
                     "JSON pointer of each to its value (+inf, -inf or nan)")

def _pointer_token(key: Any) -> str:
    return str(key).replace("~", "~0").replace("/", "~1")


def json_clean(obj, non_finite: dict | None = None, path: str = ""):
    """Return ``obj`` as JSON data (what results.json holds).

    Keys starting with ``_`` (in-memory data such as mode vectors) are dropped, numpy scalars
    become Python numbers and non-finite floats ``None``; when ``non_finite`` is a dict, the JSON
    pointer (RFC 6901, relative to ``path``) of each of those is recorded in it with its value
    (``"+inf"``, ``"-inf"`` or ``"nan"``).

    A results dictionary holds about a million numbers at 100k DOFs (every node of every state):
    the scalars of a container are handled in its own loop, and a pointer is built only for a
    container or a number that is not finite.
    """
    if isinstance(obj, (dict, list, tuple)):
        return _clean(obj, non_finite, path)
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        if non_finite is not None:
            non_finite[path] = _non_finite_word(obj)
        return None
    return obj


def _non_finite_word(v: float) -> str:
    return "nan" if math.isnan(v) else ("+inf" if v > 0 else "-inf")


_PLAIN = (str, int, bool, type(None))


class PlainRecords(list):
    """A list of flat dicts that are JSON data already: keys are strings not starting with ``_``,
    values str, int, bool, None or finite floats (checked by whoever builds it, e.g. the contact
    nodes of a state, app/study/run.py). :func:`json_clean` takes it as it is: a 100k-DOF study
    has about a million such numbers."""


def _clean(obj, non_finite: dict | None, path: str):
    """:func:`json_clean` of a dict, list or tuple."""
    if type(obj) is PlainRecords:
        return obj
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            if isinstance(k, str) and k.startswith("_"):
                continue
            out[k] = _value(v, non_finite, path, k)
        return out
    return [_value(v, non_finite, path, i) for i, v in enumerate(obj)]


def _value(v, non_finite: dict | None, path: str, key):
    """One entry ``key`` of the container at ``path``, cleaned."""
    t = type(v)
    if t is float:
        if v - v == 0.0:                 # finite (inf - inf and nan - nan are nan)
            return v
    elif t in _PLAIN:
        return v
    elif isinstance(v, (dict, list, tuple)):
        return _clean(v, non_finite, f"{path}/{_pointer_token(key)}")
    else:
        if isinstance(v, np.generic):
            v = v.item()
        if not isinstance(v, float) or math.isfinite(v):
            return v
    if non_finite is not None:
        non_finite[f"{path}/{_pointer_token(key)}"] = _non_finite_word(v)
    return None


def dumps_document(doc: Mapping) -> str:
    """The text of a results.json document.

    The top-level keys and the entries of the top-level lists (each state, each stage) are one
    per line, everything below is compact. Written by the C encoder of :mod:`json` (``indent``
    would need its pure-Python encoder: several seconds for the 20 MB of a 100k-DOF study).
    """
    return _dumps(doc, 0)


def _dumps(obj, depth: int) -> str:
    pad = " " * (depth + 1)
    if depth < 2 and isinstance(obj, dict) and obj:
        # a key as json.dumps writes it (True -> "true", None -> "null", 3 -> "3")
        items = (f"{pad}{json.dumps(k if isinstance(k, str) else json.dumps(k))}: {_dumps(v, depth + 1)}"
                 for k, v in obj.items())
        return "{\n" + ",\n".join(items) + "\n" + " " * depth + "}"
    if depth < 2 and isinstance(obj, list) and obj:
        return "[\n" + ",\n".join(pad + _dumps(v, depth + 1) for v in obj) + "\n" + " " * depth + "]"
    return json.dumps(obj, allow_nan=False)


def to_document(results: Mapping) -> dict:
    """The results.json document of a results dictionary.

    ``format_version``, the results as JSON data (:func:`json_clean`) and, when some numbers are
    not finite, the ``non_finite`` block (``reason``, and ``values``: JSON pointer ->
    ``"+inf"``/``"-inf"``/``"nan"``).

    Parameters
    ----------
    results
        A study's results as a dictionary (:meth:`app.io.result.StudyResult.to_dict`).

    Returns
    -------
    dict
        JSON data with only finite numbers (``json.dumps(..., allow_nan=False)`` accepts it).
    """
    non_finite: dict[str, str] = {}
    doc = {"format_version": FORMAT_VERSION, **json_clean(dict(results), non_finite)}
    doc["format_version"] = FORMAT_VERSION      # this format's, also for results read from an older file
    doc.pop("non_finite", None)
    if non_finite:
        doc["non_finite"] = {"reason": NON_FINITE_REASON, "values": non_finite}
    return doc


_NON_FINITE = {"+inf": math.inf, "inf": math.inf, "-inf": -math.inf, "nan": math.nan}


def _strings_to_floats(obj):
    if isinstance(obj, dict):
        return {k: _strings_to_floats(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_strings_to_floats(v) for v in obj]
    if isinstance(obj, str) and obj in ("inf", "-inf"):
        return _NON_FINITE[obj]
    return obj


def _renamed(out: dict, version: int) -> dict:
    """``out`` with the keys of :data:`RENAMED` under their format 3 names (formats before 3)."""
    if version >= 3:
        return out
    for section, names in RENAMED.items():
        if isinstance(out.get(section), dict):
            out[section] = {names.get(k, k): v for k, v in out[section].items()}
    return out


def from_document(doc: Mapping) -> dict:
    """The results dictionary of a results.json document of any format version.

    Its non-finite numbers are floats again (format 1: the strings ``"inf"``/``"-inf"``; formats 2
    and 3: the ``non_finite`` block, which the returned dictionary no longer holds), and the keys of
    formats 1 and 2 that carried a unit have their format 3 names (:data:`RENAMED`).

    Parameters
    ----------
    doc
        A parsed results.json (``json.loads`` of the file).

    Returns
    -------
    dict
        A new dictionary; ``doc`` is not changed.

    Raises
    ------
    ValueError
        For a format version newer than this app's, or a ``non_finite`` pointer that names no number.
    """
    version = doc.get("format_version", 0)
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise ValueError(f"results.json format_version = {version!r}: this app reads formats up to {FORMAT_VERSION}")
    if version < 2:
        return _renamed(_strings_to_floats(dict(doc)), version)
    out = json.loads(json.dumps(dict(doc)))            # a deep copy of the JSON data
    block = out.pop("non_finite", None) or {}
    for pointer, value in (block.get("values") or {}).items():
        *parents, last = [t.replace("~1", "/").replace("~0", "~") for t in pointer.split("/")[1:]]
        node: Any = out
        try:
            for token in parents:
                node = node[int(token)] if isinstance(node, list) else node[token]
            key = int(last) if isinstance(node, list) else last
            if node[key] is not None or value not in _NON_FINITE:
                raise ValueError
            node[key] = _NON_FINITE[value]
        except (KeyError, IndexError, TypeError, ValueError):
            raise ValueError(f"results.json non_finite: {pointer} = {value!r} names no null number") from None
    return _renamed(out, version)                      # after the pointers, which use the file's names
