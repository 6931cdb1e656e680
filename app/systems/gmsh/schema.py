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

from typing import Annotated, Any, ClassVar, Literal, Optional

from pydantic import Field, ValidationInfo, field_validator, model_validator

from app.systems.gmsh.sections import Material, Obstacle, Phase
from app.systems.schema import (
    ELEMENT_HELP,
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
        check_element(self.element, self.degree, self.poisson_ratios())
        return self

    def poisson_ratios(self) -> dict[str, float]:
        """Every material's Poisson's ratio by its key (``material.nu``, ``materials.<surface>.nu``,
        ``obstacle.material.nu``)."""
        named = {"material.nu": self.material.nu} if self.material else {
            f"materials.{k}.nu": m.nu for k, m in self.materials.items()}
        if self.obstacle.type == "body" and self.obstacle.material is not None:
            named["obstacle.material.nu"] = self.obstacle.material.nu
        return named

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
        check_mixed_analyses(scene, {f"system.{k}": v for k, v in scene.system.poisson_ratios().items()})
        if scene.loading is not None:
            raise SystemPathError("loading", scene.loading.model_dump(), "not allowed for a gmsh system: give "
                                  "system.program (the phases of the loading)")
