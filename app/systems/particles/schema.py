"""Scene schema of ``system.type: two_particles``: the paper's two-particle system (section 5, Fig. 1).

    system: {type: two_particles, k: 1.0, m: 1.0, phi_deg: 30, signs: [1, 1]}
    system: {..., obstacle: {type: circle, radius: 50, side: outside}, normal_reaction: 2.0}
    system: {..., support: {k_T: 500, k_N: 800, m: 1.0}}   # on a third, elastically supported particle

A single equilibrium state (both particles in impending slip with the signs given): no
``loading`` section, and no mesh for ParaView files or screenshots.
"""
from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal, Optional

from pydantic import Field, field_validator, model_validator

from app.common.validation import PathError, Strict
from app.systems.schema import PosFloat


class ParticleObstacle(Strict):
    """The rigid obstacle both particles rest on: the paper's straight line, or a circle of radius
    ``radius`` with the particles outside it (``side: outside``, a convex cylinder) or inside it
    (``side: inside``, a concave bore). The springs' matrix is written in each particle's own
    contact frame, so the circle's centre plays no part (docs/method.md section 8)."""

    type: Literal["line", "circle"] = Field("line", description="line (the paper's) or circle")
    radius: Optional[PosFloat] = Field(None, description="radius of the circle [mm] (type circle only)")
    side: Optional[Literal["outside", "inside"]] = Field(
        None, description="where the particles are: outside (convex cylinder) or inside (concave bore) (type circle only)")

    @model_validator(mode="after")
    def _keys_of_type(self) -> "ParticleObstacle":
        from app.systems.obstacle_schema import check_circle_keys
        check_circle_keys(self, ("radius", "side"), ())
        return self

    def curvature(self) -> float:
        """Signed curvature (dN/ds = kappa T): -1/R outside a circle, +1/R inside, 0 on the line."""
        if self.type == "line":
            return 0.0
        return (-1.0 if self.side == "outside" else 1.0) / self.radius


class Support(Strict):
    """A deformable obstacle for the two particles: a third particle (the obstacle body) of mass ``m``
    held by springs ``k_T`` (tangential) and ``k_N`` (normal) to the ground; both particles touch it
    (docs/method.md section 10: the contact DOFs are relative to it)."""

    k_T: PosFloat = Field(description="tangential spring of the support particle to the ground [N/mm]")
    k_N: PosFloat = Field(description="normal spring of the support particle to the ground [N/mm]")
    m: PosFloat = Field(description="mass of the support particle [tonne]")


class TwoParticles(Strict):
    """The two-particle system of the paper, section 5, Fig. 1 (docs/method.md section 4)."""

    has_fields: ClassVar[bool] = False      # no mesh: no ParaView files, no screenshots
    refinable: ClassVar[bool] = False       # no mesh to refine
    type: Literal["two_particles"]
    k: PosFloat = Field(description="spring stiffness [N/mm]")
    m: PosFloat = Field(description="particle mass [tonne]")
    phi_deg: Annotated[float, Field(gt=0, lt=90, allow_inf_nan=False)] = Field(
        description="angle of the inclined springs with the horizontal [deg]")
    signs: tuple[Literal[-1, 1], Literal[-1, 1]] = Field(
        description="S1, S2: signs of the static tangential reactions (both particles in impending slip)")
    obstacle: ParticleObstacle = Field(ParticleObstacle(), description="the rigid obstacle: line (default) or circle")
    support: Optional[Support] = Field(None, description="a deformable obstacle: the particles rest on a third, "
                                       "elastically supported particle (straight obstacle only)")
    normal_reaction: PosFloat = Field(1.0, description="P = -r_N of each particle [N] (enters the pencils "
                                      "only on a curved obstacle, through kappa P)")

    @field_validator("signs", mode="before")
    @classmethod
    def _signs_are_ints(cls, v: Any) -> Any:
        if (not isinstance(v, (list, tuple)) or len(v) != 2
                or any(isinstance(s, bool) or not isinstance(s, int) or s not in (-1, 1) for s in v)):
            raise ValueError("allowed: a list of two signs [S1, S2], each the integer -1 or 1")
        return v

    @model_validator(mode="after")
    def _support_on_a_line(self) -> "TwoParticles":
        if self.support is not None and self.obstacle.type != "line":
            raise PathError("support", self.support.model_dump(), "a supported particle is a straight obstacle: "
                            "not allowed with obstacle type circle")
        return self

    @classmethod
    def check_scene(cls, scene: Any) -> None:
        """Scene-level checks (called by :class:`app.scene.schema.Scene`): a single state has no loading;
        there is no mesh to draw."""
        if scene.loading is not None:
            raise PathError("loading", scene.loading.model_dump(),
                            "not allowed for a two_particles system (a single equilibrium state): "
                            "remove 'loading', or use a block system")
        from app.systems.schema import no_field_outputs
        no_field_outputs(scene, "needs a mesh: not applicable, a two_particles system has no mesh (use plots and report)")
