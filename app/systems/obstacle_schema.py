"""Shared checks of the ``obstacle`` sections (straight line or circle; docs/method.md section 8).

Kept free of PETSc and DOLFINx. A section has ``type: line`` (the default) or ``type: circle``;
each type's keys are refused with the other, and a circle's own keys are required, each with a
one-line error naming the key, the value and what is allowed.
"""
from __future__ import annotations

from typing import Any

from app.common.validation import PathError


def check_circle_keys(model: Any, circle_keys: tuple[str, ...], line_keys: tuple[str, ...]) -> None:
    """Raise :class:`PathError` unless the keys given match ``model.type``."""
    given = model.model_fields_set
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
