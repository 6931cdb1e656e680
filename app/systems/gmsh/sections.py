"""The sections of a Gmsh body's scene (``system.type: gmsh``, app/systems/gmsh/schema.py): its
material, its obstacle (a rigid line, circle or curve, or a second, deformable body) and the
phases of its loading program."""
from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Optional

import numpy as np
from pydantic import Field, PrivateAttr, field_validator, model_validator

from app.systems.schema import Finite, PosFloat, StrictModel, SystemPathError

Vec2 = tuple[Finite, Finite]


class Material(StrictModel):
    """Isotropic linear elastic material (E [stress], nu, density [mass/length^3])."""

    E: PosFloat
    nu: Annotated[float, Field(gt=-1.0, le=0.5, allow_inf_nan=False)] = Field(
        description="Poisson's ratio, -1 < nu < 1/2 (1/2, incompressible: element mixed only)")
    density: PosFloat = 1.2e-9


class Obstacle(StrictModel):
    """The obstacle. ``type: line`` (the default): a straight line through ``point``;
    ``normal`` is the body's outward normal at contact (pointing into the obstacle; need not be a
    unit vector), or ``angle_deg``: the line's slope, i.e. the normal (0, -1) rotated
    counter-clockwise by that angle (exact for any angle). ``type: circle``: a circle of centre
    ``centre`` and radius ``radius``, the body ``outside`` it (a convex cylinder) or ``inside`` it
    (a concave bore). ``type: curve``: the physical curve ``physical`` of the Gmsh ``.geo`` file
    (a free curve, bounding no surface: not part of the body), the body on its ``left`` or
    ``right`` looking along the curve's direction (its first entity's orientation); it must have a
    continuous tangent. Gaps, frames and curvature at the contact points are exact for a circle and
    interpolated to 1e-11 of the body's size for a curve (app/loading/curve.py; docs/method.md
    section 8); the contact DOFs stay in the global axes (t = +x, n = -y). ``type: body``: the
    physical surface ``surface`` of the file is a second elastic body of material ``material``,
    held on its curves ``held`` (fixed, or moved by the program as prescribed xy curves); the
    body's contact nodes touch its curve ``contact`` (straight, or smooth: then treated as a ``curve``
    obstacle, its geometry sampled from the .geo), each paired once with a point of it (``pairing``:
    ``segment``, or ``node`` for conforming meshes), and the contact quantities are relative
    (docs/method.md section 9)."""

    type: Literal["line", "circle", "curve", "body"] = Field(
        "line", description="line (straight), circle, curve (a physical curve of the .geo file) or body (a "
        "second, deformable body of the .geo file)")
    point: Vec2 = Field((0.0, 0.0), description="a point of the obstacle line [length] (type line)")
    normal: Vec2 = Field((0.0, -1.0), description="the body's outward normal at contact (into the obstacle) (type line)")
    angle_deg: Optional[Finite] = Field(None, description="or: the line's slope, the normal (0, -1) rotated by it [deg] "
                                        "(type line)")
    centre: Optional[Vec2] = Field(None, description="centre of the circle [length] (type circle)")
    radius: Optional[PosFloat] = Field(None, description="radius of the circle [length] (type circle)")
    physical: Optional[str] = Field(None, description="the physical curve of the .geo file that is the obstacle, a "
                                    "curve of its own (type curve)")
    side: Optional[Literal["outside", "inside", "left", "right"]] = Field(
        None, description="where the body is: outside (convex cylinder) or inside (concave bore) (type circle); "
        "left or right of the curve's direction (type curve)")
    surface: Optional[str] = Field(None, description="the obstacle body's physical surface (type body)")
    contact: Optional[str] = Field(None, description="the obstacle body's physical curve facing the body's contact "
                                   "curve: straight, or smooth (a curve of a .geo) (type body)")
    held: list[str] = Field([], description="the obstacle body's physical curves held (fixed, or moved by the "
                            "program's displacement as prescribed xy curves) (type body)")
    material: Optional[Material] = Field(None, description="the obstacle body's material (type body)")
    pairing: Literal["segment", "node"] = Field(
        "segment", description="node-to-segment: each contact node faces a point of a segment of the obstacle's "
        "contact curve (any meshes); node: each faces a node of it at the same place (conforming meshes) (type body)")
    _curve: Any = PrivateAttr(None)          # the SmoothCurve, set by GmshBody once the file is read
    _line: Any = PrivateAttr(None)           # a body's contact line (point, outward normal), set when meshed

    @model_validator(mode="after")
    def _one_way(self) -> "Obstacle":
        from app.systems.obstacle_schema import check_body_keys, check_circle_keys, check_curve_keys, given_keys
        check_body_keys(self)
        if self.type == "body":
            return self
        if self.type == "curve" or "physical" in self.model_fields_set:
            check_curve_keys(self)
            return self
        check_circle_keys(self, ("centre", "radius", "side"), ("point", "normal", "angle_deg"))
        if self.type == "circle" and self.side not in ("outside", "inside"):
            raise SystemPathError("side", self.side, "allowed with type: circle: outside (the body outside a convex "
                                  "cylinder) or inside (the body inside a concave bore)")
        if self.angle_deg is not None and "normal" in given_keys(self):
            raise SystemPathError("angle_deg", self.angle_deg, "give either normal or angle_deg, not both")
        return self

    @field_validator("normal")
    @classmethod
    def _nonzero(cls, v: Vec2) -> Vec2:
        if max(abs(v[0]), abs(v[1])) < 1e-100:
            raise ValueError("the normal must be a non-zero vector [nx, ny] (components up to 1e-100 count as 0)")
        return v

    @property
    def curved(self) -> bool:
        """A circle, a curve, or an obstacle body's curved contact curve: exact or interpolated gaps,
        frames per node and curvature terms (a line and a straight contact curve are not)."""
        return self.type in ("circle", "curve") or (self.type == "body" and self._curve is not None)

    def frame(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit tangent t and outward normal n of the contact DOFs, with t = (-n_y, n_x) (for
        n = -y, t = +x); for a circle or a curve the global axes (each node's contact frame is
        then its own, app/loading/curved.py)."""
        if self.type == "body" and not self.curved:
            n = np.array(self.body_line()[1], dtype=float)
            return np.array([-n[1], n[0]]), n
        if self.type != "line":
            return np.array([1.0, 0.0]), np.array([0.0, -1.0])
        if self.angle_deg is not None:
            a = math.radians(self.angle_deg)
            n = np.array([math.sin(a), -math.cos(a)])
        else:
            n = np.array(self.normal, dtype=float)
            n /= np.max(np.abs(n))              # scaled first: no overflow or underflow in the norm
            n /= np.linalg.norm(n)
        return np.array([-n[1], n[0]]), n

    def geometry(self, ref=None):
        """The curved obstacle's geometry (app/loading/curved.py ``Circle`` anchored in the
        direction of the point ``ref``, or the curve of app/loading/curve.py with its arc
        coordinate measured from ``ref``'s closest point), None for a line."""
        if self.type == "curve" or self.curved and self.type == "body":
            import copy
            return self._curve if ref is None else copy.copy(self._curve).set_reference(ref)   # arrays shared
        if self.type != "circle":
            return None          # a line, or a body's straight contact curve
        from app.loading.curved import Circle
        return Circle(self.centre, self.radius, self.side, ref)

    def clearance(self, xy: np.ndarray) -> np.ndarray:
        """Gaps of the points ``xy`` (n, 2): ``(p - x) . n`` for a line, exact for a circle."""
        if self.curved:
            xy = np.atleast_2d(xy)
            return self.geometry(np.mean(xy, axis=0)).gap(xy)
        return (np.array(self.line_point()) - np.asarray(xy)) @ self.frame()[1]

    def coordinate(self, xy: np.ndarray) -> np.ndarray:
        """Tangential coordinate of the points ``xy`` along the obstacle: ``(x - p) . t`` for a
        line, on a circle or a curve the arc coordinate from the direction (closest point) of their mean."""
        if self.curved:
            xy = np.atleast_2d(xy)
            return self.geometry(np.mean(xy, axis=0)).arc(xy)
        return (np.asarray(xy) - np.array(self.line_point())) @ self.frame()[0]

    def line_point(self) -> tuple[float, float]:
        """A point of the straight obstacle: the line's ``point``, or a point of a body's contact curve."""
        return tuple(self.body_line()[0]) if self.type == "body" else self.point

    def body_line(self) -> tuple:
        """A body obstacle's contact line ``(point, unit outward normal of the body)``: known once the
        file is meshed (app/systems/gmsh/interface.py)."""
        if self._line is None:
            raise RuntimeError("the obstacle body's contact line is known once the mesh is read")
        return self._line

    def describe(self) -> str:
        """The obstacle in words for messages: the line's point and outward normal of the body, or the
        circle or curve as its geometry describes itself."""
        if self.type == "body":
            m = self.material
            n = tuple(float(v) + 0.0 for v in np.round(self.frame()[1], 12)) if self._line is not None else None
            shape = (f", outward normal of the body {n}" if n else
                     f", curved, the body on its {self._curve.side}" if self._curve is not None else "")
            return (f"obstacle body '{self.surface}' (E = {m.E:g}, nu = {m.nu:g}; contact curve '{self.contact}'"
                    + shape + f", node-to-{self.pairing})")
        if self.type != "line":
            return "obstacle " + self.geometry().describe()
        return f"obstacle through {tuple(self.point)} with outward normal {tuple(np.round(self.frame()[1], 12))}"


class Motion(StrictModel):
    """Increment of a prescribed curve's displacement during a phase: a rigid translation and an
    optional (linearised) rotation ``rotation_deg`` about ``about``."""

    translation: Vec2 = Field((0.0, 0.0), description="rigid translation increment [length]")
    rotation_deg: Annotated[float, Field(ge=-3600, le=3600, allow_inf_nan=False)] = Field(
        0.0, description="rotation increment, linearised, counter-clockwise [deg] (at most ten turns)")
    about: Vec2 = Field((0.0, 0.0), description="centre of the rotation [length]")


class Until(StrictModel):
    """Force control of a displacement phase: scale it to reach this normal resultant on the contact curve."""

    normal_force: PosFloat = Field(description="normal resultant on the contact curve at the phase's end [force]")


class Phase(StrictModel):
    """One phase of the loading program, applied in ``steps`` equal increments."""

    name: str = Field("", description="a label of the phase (results.json load.name)")
    steps: Annotated[int, Field(ge=1, le=100000)] = Field(1, description="equal increments of the phase")
    displacement: dict[str, Motion] = Field({}, description="motion increments of prescribed curves")
    traction: dict[str, Vec2] = Field({}, description="uniform traction increments on curves [stress]")
    force: dict[str, Vec2] = Field({}, description="total force increments, spread uniformly over curves [force]")
    gravity: Optional[Vec2] = Field(None, description="acceleration increment of the body force [length/time^2]")
    until: Optional[Until] = Field(None, description="force control: scale the phase's motion to reach it")
    stop_at_gross_sliding: bool = Field(True, description="end the path when every node in contact slips "
                                        "(never with mu = 0, where every node in contact slips)")
