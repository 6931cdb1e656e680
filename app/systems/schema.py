"""Shared pieces of the system schemas registered in :mod:`app.systems`.

Kept free of PETSc and DOLFINx so that validating a scene stays cheap. File paths in a scene are
relative to the scene file: :func:`app.scene.schema.load_scene` passes the scene's folder as the
validation context ``{"base_dir": ...}``; without it (a scene given as a dict) paths are taken
relative to the current directory.
"""
from __future__ import annotations

import math
import os
import pathlib
from typing import Annotated, Optional

from pydantic import Field, ValidationInfo

from app.common.validation import PathError, ResourcePathError, Strict  # noqa: F401 - ResourcePathError re-exported

#: the largest magnitude of a number in a scene (README "Scene files"): finite, and small enough that
#: products of a few such numbers (E x displacement x area, ...) stay finite in double precision
MAGNITUDE_MAX = 1e100
PosFloat = Annotated[float, Field(gt=0, le=MAGNITUDE_MAX, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, le=MAGNITUDE_MAX, allow_inf_nan=False)]
Finite = Annotated[float, Field(ge=-MAGNITUDE_MAX, le=MAGNITUDE_MAX, allow_inf_nan=False)]


#: the one strict base model of every scene section (app/common/validation.py): unknown keys refused,
#: booleans never taken for numbers
StrictModel = Strict


SystemPathError = PathError      # the name the system schemas use


def base_dir(info: ValidationInfo | None) -> pathlib.Path:
    """Folder that relative file paths of the scene are resolved against."""
    ctx = getattr(info, "context", None) or {}
    return pathlib.Path(ctx.get("base_dir") or ".")


# The scene's ``settings.limits`` section, defined here (not in app/scene/sections.py) because the
# system schemas read their files (matrices, Gmsh models) under these limits while a scene is validated.
class Limits(Strict):
    """Resource limits checked before any work starts (app/scene/limits.py); raise them deliberately."""

    max_states: Annotated[int, Field(ge=1, le=10**9)] = Field(
        100_000, description="most load states (normal_steps + tangential_max / tangential_step)")
    max_dofs: Annotated[int, Field(ge=1, le=10**9)] = Field(2_000_000, description="most DOFs of the block mesh")
    max_contact_nodes: Annotated[int, Field(ge=1, le=10**7)] = Field(
        20_000, description="most contact nodes on AB")
    max_memory_gb: Optional[Annotated[float, Field(gt=0, le=1e6, allow_inf_nan=False)]] = Field(
        None, description="largest memory estimate accepted [GiB]; null: 80 % of the machine's RAM")
    max_file_seconds: Annotated[float, Field(gt=0, le=86400, allow_inf_nan=False)] = Field(
        60.0, description="most seconds Gmsh may take to read or mesh system.file (in its sandbox)")

    def memory_cap(self) -> tuple[float, str]:
        """(bytes, how it was set): ``max_memory_gb``, else 80 % of the machine's RAM (inf if unknown)."""
        if self.max_memory_gb is not None:
            return self.max_memory_gb * 2**30, f"settings.limits.max_memory_gb = {self.max_memory_gb}"
        try:
            ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            return math.inf, "no limit (RAM unknown)"
        return 0.8 * ram, f"80 % of this machine's RAM ({ram / 2**30:.1f} GiB; set settings.limits.max_memory_gb)"


def context_limits(info: ValidationInfo | None):
    """The scene's ``settings.limits`` passed in the validation context (None: the defaults)."""
    ctx = getattr(info, "context", None) or {}
    return ctx.get("limits")


def file_version(path: pathlib.Path) -> tuple:
    """Cache key of a file's current version: (path, modification time in ns, size)."""
    st = path.stat()
    return (str(path), st.st_mtime_ns, st.st_size)


def resolve_file(key: str, value: str, info: ValidationInfo | None) -> pathlib.Path:
    """Absolute path of an existing, readable file named in the scene (relative to the scene file)."""
    if not isinstance(value, str) or not value.strip():
        raise SystemPathError(key, value, "allowed: a file path (relative to the scene file)")
    if info is not None and isinstance(info.context, dict) and info.context.get("files") is False:
        raise SystemPathError(key, value, "a scene stored in a results folder names files, and a path read from "
                                          "there is never opened: give the scene file yourself (export --scene)")
    try:
        path = pathlib.Path(value).expanduser()
        if not path.is_absolute():
            path = base_dir(info) / path
        path = path.resolve()
        exists, is_file = path.exists(), path.is_file()
    except (OSError, ValueError, RuntimeError) as err:     # e.g. a NUL byte, a name too long, a loop
        raise SystemPathError(key, value, f"not a usable file path ({err})") from None
    if not exists:
        raise SystemPathError(key, value, f"no such file ({path})")
    if not is_file:
        raise SystemPathError(key, value, f"not a file ({path})")
    return path


def no_field_outputs(scene, why: str) -> None:
    """Refuse ``outputs.paraview``/``outputs.screenshots`` written by the user for a system type
    without a mesh: one line naming the key and ``why``. When they are on only by default (not in
    the scene), the run skips them with a "not applicable" note (app/io/fields.py)."""
    given = getattr(scene.outputs, "model_fields_set", {"paraview", "screenshots"})
    for key in ("paraview", "screenshots"):
        if key in given and getattr(scene.outputs, key):
            raise SystemPathError(f"outputs.{key}", True, why)


#: the finite elements of the meshed bodies (``system.element``)
ELEMENT_HELP = ("displacement (P1 or P2 by degree), or mixed: Taylor-Hood P2-P1 displacement and pressure "
                "(degree 2), free of volumetric locking up to the incompressible nu = 1/2")


def check_element(element: str, degree: int, poisson: dict) -> None:
    """The element's one-line refusals: the mixed element needs ``degree: 2``; a Poisson's ratio of
    1/2 (``poisson``: key -> nu) needs the mixed element."""
    if element == "mixed" and degree != 2:
        raise PathError("element", element, "the mixed element is Taylor-Hood P2-P1: give degree: 2")
    for key, nu in poisson.items():
        if nu == 0.5 and element != "mixed":
            raise PathError(key, nu, "an incompressible material (nu = 1/2) needs element: mixed (with degree: 2); "
                            "the displacement element allows nu < 1/2")


def element_name(element: str, degree: int) -> str:
    """The element in words: ``P1``, ``P2``, ``P2-P1 mixed``."""
    return "P2-P1 mixed" if element == "mixed" else f"P{degree}"


#: the analysis that needs the pressure eliminated by a Schur complement (the values of (19)),
#: which needs an invertible pressure block, nu < 1/2 (docs/method.md section 10)
ELIMINATED_ANALYSES = ("necessary",)


def check_mixed_analyses(scene, poisson: dict) -> None:
    """The mixed element's analyses: at nu = 1/2 (``poisson``: key -> nu) the pressure is a
    constraint and (19) is unbounded below at every state with slip nodes, so the necessary
    condition is refused there; the ``transient`` dynamics is not built for the mixed element.
    Each is refused in one line."""
    if getattr(scene.system, "element", "displacement") != "mixed":
        return
    if getattr(scene, "transient", None) is not None:
        raise PathError("transient", scene.transient.model_dump(), "is not available with system.element: mixed "
                        "(the dynamics and its divergence mode are built for the displacement element)")
    half = [k for k, nu in poisson.items() if nu == 0.5]
    if "necessary" in scene.analyses and half:
        raise PathError("analyses", list(scene.analyses), f"necessary is not available with system.element: mixed "
                        f"and {half[0]} = 0.5 (the pressure is a constraint there, and the smallest eigenvalue of "
                        "sym K*(mu) falls like -1/(1 - 2 nu) at states with slip nodes: (19) holds at every such "
                        "state, docs/method.md section 10); allowed: sufficient, mceip_mu, mceip_lambda2, enumerate")
