"""Shared checks of the ``obstacle`` sections (straight line, circle or curve; docs/method.md section 8).

Kept free of PETSc and DOLFINx. A section has ``type: line`` (the default) or ``type: circle``;
each type's keys are refused with the other, and a circle's own keys are required, each with a
one-line error naming the key, the value and what is allowed.
"""
from __future__ import annotations

from typing import Any

from app.common.validation import PathError


def check_circle_keys(model: Any, circle_keys: tuple[str, ...], line_keys: tuple[str, ...]) -> None:
    """Raise :class:`PathError` unless the keys given match ``model.type`` (:func:`given_keys`)."""
    given = given_keys(model)
    if model.type == "line":
        for key in circle_keys:
            if key in given:
                raise PathError(key, getattr(model, key), f"allowed only with type: circle (this obstacle is "
                                f"type: line; allowed keys: type{''.join(', ' + k for k in line_keys)})")
        return
    for key in line_keys:
        if key in given:
            raise PathError(key, getattr(model, key), "allowed only with type: line (this obstacle is type: circle; "
                            f"allowed keys: type, {', '.join(circle_keys)})")
    for key in circle_keys:
        if getattr(model, key) is None:
            allowed = {"radius": "a number > 0 [length]", "side": "outside (the body outside a convex cylinder) or "
                       "inside (the body inside a concave bore)", "centre": "[x, y] [length]"}[key]
            raise PathError(key, None, f"missing: a circle needs {key} (allowed: {allowed})")


BODY_KEYS = ("surface", "contact", "held", "material", "pairing")


def check_body_keys(model: Any) -> None:
    """A ``type: body`` obstacle (gmsh bodies) has ``surface``, ``contact`` and ``material`` (and
    ``held``, ``pairing``), and no key of the other types; the other types have none of these."""
    given = given_keys(model)
    if model.type != "body":
        for key in BODY_KEYS:
            if key in given:
                raise PathError(key, _shown(getattr(model, key)), f"allowed only with type: body (this obstacle is "
                                f"type: {model.type})")
        return
    for key in ("point", "normal", "angle_deg", "centre", "radius", "side", "physical"):
        if key in given:
            raise PathError(key, getattr(model, key), "not allowed with type: body (allowed keys: type, "
                            + ", ".join(BODY_KEYS) + ")")
    for key, what in (("surface", "the name of the obstacle body's physical surface"),
                      ("contact", "the name of its physical curve facing the body's contact curve"),
                      ("material", "{E, nu, density}: the obstacle body's material")):
        if getattr(model, key) is None:
            raise PathError(key, None, f"missing: an obstacle body needs {key} ({what})")


def _shown(v: Any) -> Any:
    return v.model_dump() if hasattr(v, "model_dump") else v


def check_curve_keys(model: Any) -> None:
    """A ``type: curve`` obstacle (gmsh bodies) has ``physical`` and ``side: left|right`` only."""
    given = given_keys(model)
    if model.type != "curve":
        raise PathError("physical", model.physical, f"allowed only with type: curve (this obstacle is type: {model.type})")
    for key in ("point", "normal", "angle_deg", "centre", "radius", *BODY_KEYS):
        if key in given:
            raise PathError(key, _shown(getattr(model, key)), "not allowed with type: curve (allowed keys: type, "
                            "physical, side)")
    if model.physical is None:
        raise PathError("physical", None, "missing: a curve obstacle needs physical (the name of a physical curve "
                        "of the .geo file, a curve of its own)")
    if model.side not in ("left", "right"):
        raise PathError("side", model.side, "allowed with type: curve: left or right (the side of the body, looking "
                        "along the curve's direction)")


def given_keys(model: Any) -> set[str]:
    """The keys given to ``model`` with a value other than their default: a key given with its
    default value changes nothing, and a stored scene (results.json ``scene_config``, which lists
    every default) validates again."""
    fields = type(model).model_fields

    def value(k: str) -> Any:
        v = getattr(model, k)
        return tuple(v) if isinstance(v, list) else v
    return {k for k in model.model_fields_set if k not in fields or value(k) != _default(fields[k])}


def _default(field) -> Any:
    """A field's default value, as the model holds it (a list default compared as a tuple too)."""
    d = field.get_default(call_default_factory=True)
    return tuple(d) if isinstance(d, list) else d
