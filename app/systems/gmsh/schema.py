"""Scene schema of ``system.type: gmsh``: a 2D elastic body from a Gmsh file, a straight rigid
obstacle, and a loading program.

    system:
      type: gmsh
      file: block.geo              # .geo (meshed in 2D by gmsh) or .msh, relative to the scene file
      contact: AB                  # physical curve that may touch the obstacle
      prescribed: {CD: xy}         # physical curves whose displacement components the program prescribes
      material: {E: 5.0, nu: 0.48, density: 1.2e-9}   # or materials: {<physical surface>: {...}}
      degree: 1                    # P1 or P2
      plane: stress                # or strain
      thickness: 9.6
      obstacle: {point: [0, 0], normal: [0, -1]}      # a straight line; normal: the body's outward normal
      # or: obstacle: {type: circle, centre: [40, -200], radius: 200, side: outside}
      # or: obstacle: {type: curve, physical: ground, side: left}   # a free physical curve of the .geo
      program:                     # phases; each starts from the end of the previous one
        - {steps: 10, displacement: {CD: {translation: [0, -1]}}, until: {normal_force: 55}}
        - {steps: 310, displacement: {CD: {translation: [-6.2, 0]}}}

A body that no prescribed curve holds (e.g. resting on an inclined plane under gravity) has rigid
motions that only the obstacle stops; the contact solver needs a non-singular K, so such a body
needs ``foundation: k``: an elastic foundation ``k t int u.v dx`` on the whole body. Choose k
small against E / L^2 (e.g. 1e-6 of it): it carries a fraction of the load of order k L^2 / E
while the body sticks, and lets a body slide (by excess force / k) when friction cannot hold it.

Curves neither ``contact`` nor ``prescribed`` are traction-free unless a phase loads them
(``traction`` per unit length, or ``force``: a total force spread uniformly over the curve).
``gravity`` adds the body force density x acceleration. ``until: {normal_force: F}`` scales the
phase's increments so that the normal resultant on the contact curve is F at its end (exact in one
rescaling when the phase starts from the unloaded, touching state: the incremental problems are
then positively homogeneous; otherwise bracketing and regula falsi). A circle obstacle has exact gaps
and frames, a curve of the .geo file interpolated ones (docs/method.md section 8, docs/curved.md); their
increments are never homogeneous. A second, deformable body of the file may be the obstacle:
``obstacle: {type: body, surface: plate, contact: top, held: [bottom], material: {...}}``
(app/systems/gmsh/interface.py; docs/method.md section 9). Not modelled: a curve from a .msh
file, large rotations (rotations are linearised), contact of nodes outside the
``contact`` curve.
"""
from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar, Literal, Optional

import numpy as np
from pydantic import Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from app.systems.schema import (
    ELEMENT_HELP,
    Finite,
    PosFloat,
    ResourcePathError,
    StrictModel,
    SystemPathError,
    base_dir,
    check_element,
    check_mixed_analyses,
    context_limits,
    element_name,
    resolve_file,
)

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


class GmshBody(StrictModel):
    """A 2D body meshed by Gmsh (physical groups name its curves and surfaces)."""

    type: Literal["gmsh"]
    has_fields: ClassVar[bool] = True       # ParaView files and screenshots (app/io/fields.py)
    refinable: ClassVar[bool] = True        # a .geo's mesh: refinement by its size factor (app/study/refinement.py)
    file: str = Field(description="Gmsh .geo or .msh file, relative to the scene file")
    mesh_size_factor: PosFloat = Field(1.0, description="a .geo's characteristic lengths are multiplied by it "
                                       "(Gmsh's Mesh.CharacteristicLengthFactor: 0.5 halves the element size); "
                                       "a .msh file's mesh is used as it is")
    contact: str = Field(description="physical curve that may touch the obstacle")
    prescribed: dict[str, Literal["x", "y", "xy"]] = Field(
        {}, description="physical curves whose displacement components the program prescribes")
    material: Optional[Material] = Field(None, description="one material for the whole body")
    materials: dict[str, Material] = Field({}, description="or: a material per physical surface")
    degree: Literal[1, 2] = 1
    element: Literal["displacement", "mixed"] = Field("displacement", description=ELEMENT_HELP)
    plane: Literal["stress", "strain"] = "stress"
    thickness: PosFloat = 1.0
    mass: Literal["consistent", "lumped"] = "consistent"
    obstacle: Obstacle = Field(Obstacle(), description="the obstacle: a rigid straight line (default), circle or "
                               "curve, or a second, deformable body")
    foundation: Optional[PosFloat] = Field(None, description="weak elastic foundation for a body nothing holds "
                                           "[stress/length]")
    program: Annotated[list[Phase], Field(min_length=1, max_length=1000)] = Field(
        description="the loading program: phases")

    def load_states(self) -> tuple[int, str]:
        """(equilibrium states of the program, the key that sets them) for the pre-flight (app/scene/limits.py)."""
        return 1 + sum(ph.steps for ph in self.program), "system.program[].steps"

    # ---- a mesh-refinement study (app/study/refinement.py) ----
    #: the key of the ``refinement`` section that lists the body's levels, and what they are
    refinement_key: ClassVar[str] = "size_factors"
    refinement_help: ClassVar[str] = "the .geo's characteristic lengths times each factor, e.g. [2, 1, 0.5]"
    #: the cell size of a level (relative to the .geo's), its label and its unit's quantity (none)
    refinement_h: ClassVar[tuple[str, Optional[str]]] = ("mesh-size factor (the .geo's characteristic lengths "
                                                         "times it)", None)

    def refinement_problem(self) -> Optional[str]:
        """Why this body cannot be refined: a ``.msh`` holds one fixed mesh."""
        if not str(self.file).lower().endswith(".geo"):
            return "a refinement remeshes the body: it needs a .geo (a .msh holds one fixed mesh)"
        return None

    def level_keys(self, factor: float, degree: int, plane: str) -> dict:
        """The system keys of the refinement level ``factor``."""
        return {"mesh_size_factor": float(factor), "degree": degree, "plane": plane}

    @staticmethod
    def level_row(factor: float) -> dict:
        """The level's columns of refinement.csv (h: the factor, the cell size relative to the .geo's)."""
        return {"size_factor": float(factor), "h": float(factor)}

    @staticmethod
    def level_names(factor: float) -> tuple[str, str]:
        """The level in words and as a folder tag: ``size factor 0.5``, ``f0.5``."""
        return f"size factor {float(factor):g}", f"f{float(factor):g}"

    @staticmethod
    def one_step(data: dict) -> None:
        """Shorten the scene document ``data`` to the program's first phase in one step."""
        program = data["system"]["program"]
        data["system"]["program"] = [{**program[0], "steps": 1}]

    def describe(self, units: dict) -> str:
        """The body in one line (refinement.md)."""
        import pathlib
        mat = self.material
        what = f"E={mat.E} {units['stress']}, nu={mat.nu}" if mat is not None else "a material per surface"
        return (f"Gmsh body {pathlib.Path(self.file).name} ({self.thickness} {units['length']} thick), {what}, "
                f"a loading program of {len(self.program)} phase(s)")

    def file_sizes(self) -> tuple[int, int, str]:
        """(DOFs, contact nodes, the key that sets them) from the mesh read at validation (app/scene/limits.py)."""
        import pathlib

        from app.systems.gmsh.mesh import mesh_sizes, model_info
        dofs, contact = mesh_sizes(pathlib.Path(self.file), self.degree, self.all_prescribed(), self.contact,
                                   self.mesh_size_factor)
        if self.element == "mixed":          # + the P1 pressure, a DOF per vertex
            dofs += model_info(pathlib.Path(self.file), pathlib.Path(self.file).name, None, None,
                               self.mesh_size_factor).n_nodes
        return dofs, contact, "system.file"

    @model_validator(mode="before")
    @classmethod
    def _tags_as_names(cls, data: Any, info: ValidationInfo) -> Any:
        """Unnamed physical groups are named by their tag: accept ``contact: 3`` for ``'3'``; a named
        group may also be given by its tag (``contact: 1`` for ``Physical Curve("AB", 1)``)."""
        if not isinstance(data, dict):
            return data
        alias = {1: {}, 2: {}}
        try:
            from app.systems.gmsh.mesh import model_info
            path = resolve_file("", data.get("file"), info)
            mi = model_info(path, path.name, context_limits(info), (base_dir(info), path.parent),
                            float(data.get("mesh_size_factor", 1.0)))
            for dim, groups in ((1, mi.curves), (2, mi.surfaces)):
                alias[dim] = {str(tag): name for name, (tag, _) in groups.items() if str(tag) not in groups}
        except Exception:     # noqa: BLE001 - a bad file is reported by the file validator
            pass

        def one(v: Any, dim: int = 1) -> Any:
            v = str(v) if isinstance(v, int) and not isinstance(v, bool) else v
            return alias[dim].get(v, v) if isinstance(v, str) else v

        def names(d: Any, dim: int = 1) -> Any:
            return {one(k, dim): v for k, v in d.items()} if isinstance(d, dict) else d
        data = dict(data)
        if "contact" in data:
            data["contact"] = one(data["contact"])
        ob = data.get("obstacle")
        if isinstance(ob, dict) and ob.get("type") == "body":
            ob = dict(ob, **{k: one(ob[k], dim) for k, dim in (("surface", 2), ("contact", 1)) if k in ob})
            if isinstance(ob.get("held"), list):
                ob["held"] = [one(v) for v in ob["held"]]
            data["obstacle"] = ob
        for key, dim in (("prescribed", 1), ("materials", 2)):
            data[key] = names(data[key], dim) if key in data else data.get(key, {})
        if isinstance(data.get("program"), list):
            data["program"] = [dict(ph, **{k: names(ph[k]) for k in ("displacement", "traction", "force") if k in ph})
                               if isinstance(ph, dict) else ph for ph in data["program"]]
        return data

    @field_validator("file", mode="before")
    @classmethod
    def _file(cls, v: Any, info: ValidationInfo) -> Any:
        return str(resolve_file("", v, info))

    @model_validator(mode="after")
    def _groups(self, vinfo: ValidationInfo) -> "GmshBody":
        import pathlib

        from app.systems.gmsh.mesh import model_info
        path = pathlib.Path(self.file)
        shown = path.name
        try:
            if self.mesh_size_factor != 1.0 and path.suffix.lower() != ".geo":
                raise SystemPathError("mesh_size_factor", self.mesh_size_factor,
                                      f"{shown} holds its mesh: a size factor applies to a .geo's characteristic "
                                      "lengths only (give the .geo, or leave mesh_size_factor at 1)")
            info = model_info(path, shown, context_limits(vinfo), (base_dir(vinfo), path.parent),
                              self.mesh_size_factor)
        except SystemPathError as err:
            # a time or memory limit stopped Gmsh: exit status 4 (app/scene/schema.py)
            cls = ResourcePathError if getattr(err, "resource", False) else SystemPathError
            raise cls("file", shown, err.msg) from None
        curves, surfaces = info.curves, info.surfaces

        def curve(key: str, name: str) -> None:
            if name not in curves:
                allowed = ", ".join(sorted(curves)) or "none: the file defines no physical curve"
                raise SystemPathError(key, name, f"no physical curve '{name}' in {shown}; physical curves: {allowed}")
            if curves[name][1] == 0:
                raise SystemPathError(key, name, f"the physical curve '{name}' has no mesh elements")

        curve("contact", self.contact)
        if self.obstacle.type == "curve":
            from app.systems.gmsh.mesh import obstacle_curve
            self.obstacle._curve = obstacle_curve(path, shown, info, self.obstacle, self.contact,
                                                  self.mesh_size_factor)
        inner = info.inner_segments.get(self.contact, 0)
        if inner:
            raise SystemPathError("contact", self.contact, f"{inner} of the {curves[self.contact][1]} segments of the "
                                  f"physical curve '{self.contact}' lie inside the body, not on its boundary: the "
                                  "contact curve must be part of the body's boundary")
        for name in self.prescribed:
            curve(f"prescribed.{name}", name)
            if name == self.contact:
                raise SystemPathError(f"prescribed.{name}", self.prescribed[name],
                                      "the contact curve cannot also be prescribed")
        body_surfaces = set(surfaces)
        if self.obstacle.type == "body":
            self._obstacle_body(curve, surfaces, shown)
            body_surfaces.discard(self.obstacle.surface)
        if (self.material is None) == (not self.materials):
            raise SystemPathError("material", None, "give either 'material' (one material for the whole body) or "
                                  f"'materials' (one per physical surface: {', '.join(sorted(body_surfaces))})")
        if self.materials:
            for name in self.materials:
                if name not in surfaces:
                    raise SystemPathError(f"materials.{name}", None, f"no physical surface '{name}' in {shown}; "
                                          f"physical surfaces: {', '.join(sorted(surfaces))}")
                if name not in body_surfaces:
                    raise SystemPathError(f"materials.{name}", None, f"'{name}' is the obstacle body: give its "
                                          "material as obstacle.material")
            missing = sorted(body_surfaces - set(self.materials))
            if missing:
                raise SystemPathError("materials", sorted(self.materials), f"no material for the physical surface "
                                      f"'{missing[0]}': give one for each of {', '.join(sorted(surfaces))}")
        for i, ph in enumerate(self.program):
            for name, m in ph.displacement.items():
                key = f"program.{i}.displacement.{name}"
                if name not in self.all_prescribed():
                    raise SystemPathError(key, None, f"'{name}' is not a prescribed curve: list it under "
                                          f"prescribed (with its components x, y or xy)")
                comp = self.all_prescribed()[name]
                if comp != "xy" and (m.rotation_deg != 0 or m.translation[1 if comp == "x" else 0] != 0):
                    raise SystemPathError(key, m.model_dump(), f"only the {comp} component of '{name}' is prescribed: "
                                          "rotations and the other translation component need xy")
            for kind in ("traction", "force"):
                for name in getattr(ph, kind):
                    curve(f"program.{i}.{kind}.{name}", name)
                    if name in self.all_prescribed():
                        raise SystemPathError(f"program.{i}.{kind}.{name}", None,
                                              f"'{name}' is prescribed (displacement control): load another curve")
            if ph.until is not None and not ph.displacement:
                raise SystemPathError(f"program.{i}.until", ph.until.model_dump(), "needs a displacement in the "
                                      "same phase (it scales the phase's prescribed motion)")
        return self

    @model_validator(mode="after")
    def _element(self) -> "GmshBody":
        named = {"material.nu": self.material.nu} if self.material else {
            f"materials.{k}.nu": m.nu for k, m in self.materials.items()}
        if self.obstacle.type == "body" and self.obstacle.material is not None:
            named["obstacle.material.nu"] = self.obstacle.material.nu
        check_element(self.element, self.degree, named)
        return self

    def element_name(self) -> str:
        """The element in words (``P1``, ``P2``, ``P2-P1 mixed``)."""
        return element_name(self.element, self.degree)

    def _obstacle_body(self, curve, surfaces: dict, shown: str) -> None:
        """The keys of a ``type: body`` obstacle name the file's groups, apart from the body's."""
        ob = self.obstacle
        if ob.surface not in surfaces:
            raise SystemPathError("obstacle.surface", ob.surface, f"no physical surface '{ob.surface}' in {shown}; "
                                  f"physical surfaces: {', '.join(sorted(surfaces))}")
        if len(surfaces) < 2:
            raise SystemPathError("obstacle.surface", ob.surface, f"{shown} has one physical surface: the body and "
                                  "the obstacle body need one each")
        curve("obstacle.contact", ob.contact)
        if ob.contact == self.contact:
            raise SystemPathError("obstacle.contact", ob.contact, "the body's own contact curve: give the obstacle "
                                  "body's curve facing it (a curve of its own, not shared with the body)")
        for name in ob.held:
            curve("obstacle.held", name)
            if name in (self.contact, ob.contact):
                raise SystemPathError("obstacle.held", name, "a contact curve cannot be held")
            if name in self.prescribed:
                raise SystemPathError("obstacle.held", name, f"'{name}' is also under prescribed: list it once")

    def all_prescribed(self) -> dict[str, str]:
        """The curves whose displacement the program prescribes: ``prescribed`` and an obstacle
        body's ``held`` curves (both components)."""
        held = {name: "xy" for name in self.obstacle.held} if self.obstacle.type == "body" else {}
        return {**self.prescribed, **held}

    def material_of(self, surface: str) -> Material:
        """The material of the physical surface ``surface``: an obstacle body's own, the one
        ``material``, or that surface's entry of ``materials``."""
        if self.obstacle.type == "body" and surface == self.obstacle.surface:
            return self.obstacle.material
        return self.material if self.material is not None else self.materials[surface]

    @classmethod
    def check_scene(cls, scene: Any) -> None:
        """Scene-level checks: no block loading (ParaView files and screenshots work for any body); the
        analyses of the mixed element."""
        check_mixed_analyses(scene)
        if scene.loading is not None:
            raise SystemPathError("loading", scene.loading.model_dump(), "not allowed for a gmsh system: give "
                                  "system.program (the phases of the loading)")
