"""Scene schema of ``system.type: block``: the elastic block of Villechaise and Zeghloul and its
quasi-static loading (the top-level ``loading`` section), docs/method.md section 5.

    system: {type: block, length: 80, height: 40, nx: 20, ny: 10, E: 5.0, nu: 0.48}
    loading: {normal_force: 55, normal_steps: 10, tangential_step: 0.02, tangential_max: 10}

The block has a mesh (ParaView files, screenshots) and can be refined (``refinement``).
"""
from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar, Literal, Optional

from pydantic import Field, model_validator

from app.common.validation import PathError, Strict
from app.systems.schema import ELEMENT_HELP, PosFloat, check_element, check_mixed_analyses, element_name


class Loading(Strict):
    """Quasi-static loading of the block: press CD down, then drag it to the left. N and mm."""

    normal_force: PosFloat = 55.0
    normal_steps: Annotated[int, Field(ge=1, le=10000)] = 10
    tangential_step: PosFloat = 0.02
    tangential_max: PosFloat = 10.0


class Block(Strict):
    """The elastic block of Villechaise and Zeghloul (the paper's section 5). Units: mm, MPa, tonne/mm^3."""

    has_fields: ClassVar[bool] = True       # ParaView files and screenshots (app/io/fields.py)
    refinable: ClassVar[bool] = True        # a mesh-refinement study (app/study/refinement.py)
    type: Literal["block"]
    length: PosFloat = 80.0
    height: PosFloat = 40.0
    thickness: PosFloat = 9.6
    nx: Annotated[int, Field(ge=1, le=4096)] = 20
    ny: Annotated[int, Field(ge=1, le=4096)] = 10
    pattern: Literal["crossed", "right", "left", "alternate", "unstructured"] = "crossed"
    mesh_size: Optional[PosFloat] = None
    degree: Literal[1, 2] = 1
    element: Literal["displacement", "mixed"] = Field("displacement", description=ELEMENT_HELP)
    plane: Literal["stress", "strain"] = "stress"
    E: PosFloat = 5.0
    nu: Annotated[float, Field(gt=-1.0, le=0.5, allow_inf_nan=False)] = Field(
        0.48, description="Poisson's ratio, -1 < nu < 1/2 (1/2, incompressible: element mixed only)")
    density: PosFloat = 1.2e-9
    mass: Literal["consistent", "lumped"] = "consistent"

    @model_validator(mode="after")
    def _mesh_size_for_unstructured(self) -> "Block":
        if self.pattern == "unstructured" and self.mesh_size is None:
            raise PathError("mesh_size", None, "pattern 'unstructured' needs mesh_size (a positive length in mm)")
        return self

    @model_validator(mode="after")
    def _element(self) -> "Block":
        check_element(self.element, self.degree, {"nu": self.nu})
        return self

    def element_name(self) -> str:
        """The element in words (``P1``, ``P2``, ``P2-P1 mixed``)."""
        return element_name(self.element, self.degree)

    def poisson_ratios(self) -> dict[str, float]:
        """The Poisson's ratio by its key (``nu``)."""
        return {"nu": self.nu}

    @classmethod
    def check_scene(cls, scene: Any) -> None:
        """Scene-level checks (called by :class:`app.scene.schema.Scene`): the loading defaults; the
        analyses of the mixed element."""
        check_mixed_analyses(scene, {f"system.{k}": v for k, v in scene.system.poisson_ratios().items()})
        if scene.loading is None:
            object.__setattr__(scene, "loading", Loading())

    def mesh_sizes(self) -> tuple[int, int]:
        """(DOFs, contact nodes) of the block mesh (exact for structured meshes, an estimate
        otherwise); used by the resource pre-flight (app/scene/limits.py)."""
        if self.pattern == "unstructured":
            h = float(self.mesh_size)
            nx = max(1, math.ceil(self.length / h))
            ny = max(1, math.ceil(self.height / h))
            vertices = int(1.2 * (nx + 1) * (ny + 1))
            cells = 2 * nx * ny
        else:
            nx, ny = self.nx, self.ny
            vertices = (nx + 1) * (ny + 1) + (nx * ny if self.pattern == "crossed" else 0)
            cells = nx * ny * (4 if self.pattern == "crossed" else 2)
        nodes = vertices if self.degree == 1 else vertices + (vertices + cells - 1)   # + edge midpoints (Euler)
        contact = self.degree * nx + 1
        return 2 * nodes + (vertices if self.element == "mixed" else 0), contact      # + P1 pressure

    def refined(self, nx: int) -> "Block":
        """A copy of the block with ``nx`` cells along AB and ``ny`` scaled to keep the cells' aspect."""
        return self.model_copy(update={"nx": nx, "ny": max(1, round(nx * self.height / self.length))})

    # ---- a mesh-refinement study (app/study/refinement.py) ----
    #: the key of the ``refinement`` section that lists the block's levels, and what they are
    refinement_key: ClassVar[str] = "levels"
    refinement_help: ClassVar[str] = "nx, the cells along AB, e.g. [10, 20, 40]"
    #: the cell size of a level, its label and its unit's quantity (a key of the units block)
    refinement_h: ClassVar[tuple[str, Optional[str]]] = ("cell size h along the contact side", "length")

    def refinement_problem(self) -> Optional[str]:
        """Why this block cannot be refined (never: every block has a mesh of nx cells)."""
        return None

    def level_keys(self, nx: int, degree: int, plane: str) -> dict:
        """The system keys of the refinement level ``nx`` (square cells)."""
        return {"nx": int(nx), "ny": self.refined(int(nx)).ny, "degree": degree, "plane": plane}

    def level_row(self, nx: int) -> dict:
        """The level's columns of refinement.csv."""
        return {"pattern": self.pattern, "nx": int(nx), "ny": self.refined(int(nx)).ny, "h": self.length / int(nx)}

    @staticmethod
    def level_names(nx: int) -> tuple[str, str]:
        """The level in words and as a folder tag: ``nx=20``, ``nx20``."""
        return f"nx={int(nx)}", f"nx{int(nx)}"

    @staticmethod
    def one_step(data: dict) -> None:
        """Shorten the scene document ``data`` to one tangential step (the forms' compilation)."""
        loading = data.setdefault("loading", {})
        loading["tangential_max"] = loading.get("tangential_step", Loading().tangential_step)

    def describe(self, units: dict) -> str:
        """The block in one line (refinement.md)."""
        return (f"block {self.length}x{self.height}x{self.thickness} {units['length']}, {self.pattern}, "
                f"E={self.E} {units['stress']}, nu={self.nu}")

    def table_columns(self) -> dict[str, float]:
        """Extra columns of a sweep's table (app/study/sweep.py): the aspect ratio L/H."""
        return {"L_over_H": float(f"{self.length / self.height:.12g}")}
