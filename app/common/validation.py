"""Pydantic base model and one-line error helpers shared by the scene schema (app/scene/schema.py)
and the system schemas (app/systems/).

Kept free of PETSc and DOLFINx: validating a scene stays cheap.
"""
from __future__ import annotations

import reprlib
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, model_validator


class SceneError(Exception):
    """A user mistake in a scene file: ``str(err)`` is the one-line message; ``exit_code`` the CLI's
    exit status (2, or 4 when a resource limit stopped the reading of a file)."""

    def __init__(self, msg: str, exit_code: int = 2):
        super().__init__(one_line(msg))
        self.exit_code = exit_code


def one_line(text: str) -> str:
    """``text`` with every line break (as ``str.splitlines`` sees them) replaced by a space."""
    return " ".join(text.splitlines()) if text else text


class PathError(ValueError):
    """A model-level check that blames one key: ``path`` is relative to the model validated.

    :func:`app.scene.schema.format_error` turns it into ``KEY = VALUE: message``.
    """

    def __init__(self, path: str, value: Any, msg: str):
        super().__init__(msg)
        self.path, self.value, self.msg = path, value, msg


class ResourcePathError(PathError):
    """A :class:`PathError` caused by a resource limit (time, memory): exit status 4."""


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxdict, _REPR.maxlist, _REPR.maxtuple = 2, 6, 6, 6
_REPR.maxset = _REPR.maxfrozenset = 6
_REPR.maxstring, _REPR.maxlong, _REPR.maxother = 60, 40, 60


def show_value(value: Any) -> str:
    """A short one-line repr of a user value (bounded: YAML aliases can build huge or cyclic values)."""
    try:
        text = _REPR.repr(value)
    except Exception:                      # e.g. ints beyond the int-to-str digit limit
        text = f"<{type(value).__name__}>"
    text = one_line(text)
    return text if len(text) <= 160 else text[:150] + "...(cut)"


def number_kind(tp: Any) -> str | None:
    """'an integer' or 'a number' if the annotation takes numbers and no booleans, else None."""
    import typing
    found = {"int": False, "float": False, "bool": False}

    def walk(t: Any) -> None:
        if t is bool or t is str or (isinstance(t, type) and issubclass(t, BaseModel)):
            found["bool"] = True           # mixed with non-numbers: the field's own validator decides
        elif t is int:
            found["int"] = True
        elif t is float:
            found["float"] = True
        elif typing.get_origin(t) is Literal:
            for a in typing.get_args(t):
                if isinstance(a, (bool, str)):
                    found["bool"] = True
                elif isinstance(a, int):
                    found["int"] = True
                elif isinstance(a, float):
                    found["float"] = True
        else:
            for a in typing.get_args(t):
                walk(a)
    walk(tp)
    if found["bool"] or not (found["int"] or found["float"]):
        return None
    return "a number" if found["float"] else "an integer"


class Strict(BaseModel):
    """Frozen scene section that forbids unknown keys and refuses booleans where numbers are expected."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)

    @model_validator(mode="before")
    @classmethod
    def _no_booleans_for_numbers(cls, data: Any) -> Any:
        """Booleans are not numbers: YAML's ``yes``/``true`` would silently become 1."""
        if isinstance(data, dict):
            for name, v in data.items():
                field = cls.model_fields.get(name) if isinstance(name, str) else None
                kind = number_kind(field.annotation) if field is not None else None
                if kind is None:
                    continue
                if isinstance(v, bool) or (isinstance(v, (list, tuple)) and any(isinstance(x, bool) for x in v)):
                    raise PathError(name, v, f"a boolean (true/false/yes/no/on/off) is not a number: "
                                              f"allowed: {kind}" + (" (or a list of them)" if isinstance(v, (list, tuple)) else ""))
        return data
