"""Generate docs/scene-keys.md, the reference of every scene key, from the pydantic schema.

    .venv/bin/python scripts/scene_keys.py           # rewrite docs/scene-keys.md
    .venv/bin/python scripts/scene_keys.py --check   # exit 1 if docs/scene-keys.md is stale

Types, defaults and allowed ranges come from ``app.scene.schema.Scene.model_json_schema()`` (the
validation schema itself, so they cannot drift); the meaning of a key is the field's
``description`` in app/scene/schema.py when it has one, else the short text in ``MEANING`` below.
tests/test_docs.py fails when the committed file differs from this script's output: after a
schema change, run the first command and commit the result.
"""
from __future__ import annotations

import json
import pathlib
import sys
from typing import Any

from _generated import write_or_check  # beside this script: scripts/ is on sys.path

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "scene-keys.md"

#: meaning of the keys whose schema field has no description (key path -> text)
MEANING = {
    "name": "study name; also the default output folder output/<name>",
    "system": "the system: `two_particles` (paper Fig. 1), `block` (the FE block, section 5), or a type of app/systems/: "
              "`matrices` (K, M and contact DOFs from files), `gmsh` (a 2D body from a Gmsh file)",
    "mu": "Coulomb friction coefficient of the loading path and of the analyses",
    "analyses": "analyses run at every distinct classification: necessary (19), sufficient (17)-(18), "
                "mceip_mu (21)-(23), mceip_lambda2 (12)-(14), enumerate (24)-(26)",
    "mceip_lambda2_mu": "mu used by MCEIP-lambda^2 and its necessary-condition proof (null: the scene's mu)",
    "loading": "quasi-static loading of the block (a block gets the defaults when it is absent; "
               "not allowed for two_particles)",
    "settings": "solver settings (the defaults reproduce the paper's numbers)",
    "sweep": "a batch of studies (app/study/sweep.py); null: one study",
    "outputs": "files and pictures for people (app/io/, app/plot/); all off by default",
    "refinement": "a mesh-refinement study of a block scene (app/study/refinement.py)",
    "system.type": "selects the system type; the other keys of the section depend on it",
    "outputs.states[].stick": "number of stick nodes", "outputs.states[].slip": "number of slip nodes",
    "outputs.states[].free": "number of free nodes", "outputs.states[].zero": "number of zero-reaction nodes",
    "system.length": "block length AB = CD [length]", "system.height": "block height [length]",
    "system.thickness": "out-of-plane thickness (plane stress) [length]",
    "system.nx": "cells along AB", "system.ny": "cells along the height",
    "system.pattern": "triangulation of the cells: crossed (four triangles per cell, the paper's mesh), right, "
                      "left, alternate, or unstructured (Gmsh, with mesh_size)",
    "system.mesh_size": "target element size of the unstructured mesh [length]",
    "system.degree": "Lagrange degree of the displacement (P1 or P2)",
    "system.plane": "2D model: plane stress (the paper's) or plane strain",
    "system.E": "Young's modulus [stress]", "system.nu": "Poisson's ratio",
    "system.density": "mass density [mass/length^3]", "system.mass": "mass matrix: consistent or lumped",
    "loading.normal_force": "normal resultant on AB at the end of the pressing phase [force]",
    "loading.normal_steps": "increments of the pressing phase",
    "loading.tangential_step": "horizontal motion of CD per increment, towards the left [length]",
    "loading.tangential_max": "largest horizontal motion of CD (the path also ends at gross sliding) [length]",
    "settings.classify_rtol": "relative tolerance of the node classification (scale: the largest reaction)",
    "settings.mcp": "SNES VI search of the MCPs (Propositions 1-2)",
    "settings.mcp.rtol": "SNES relative tolerance", "settings.mcp.max_it": "SNES iterations per run",
    "settings.mcp.stol": "SNES step tolerance",
    "settings.mcp.accept_tol": "a candidate is accepted only if it satisfies the MCP to this scaled tolerance",
    "settings.mcp.starts": "starting eigenvalue guesses t0 of the uniform starts",
    "settings.mcp.shift_rounds": "rounds of the search above/below found values (paper section 4)",
    "settings.mcp.pattern_starts": "one-node starts and eigenvectors of neighbouring stick/slip patterns",
    "settings.mcp.pattern_eig_limit": "largest pattern size for the pattern-eigenvector starts",
    "settings.mcp.rsls_linesearch": "line search of vinewtonrsls",
    "settings.eig": "SLEPc settings of the necessary and sufficient conditions",
    "settings.eig.dense_limit": "below this size the eigenproblems are solved densely (all eigenvalues)",
    "settings.eig.nev": "eigenvalues computed above dense_limit", "settings.eig.tol": "SLEPc tolerance",
    "settings.eig.max_it": "SLEPc iterations",
    "settings.enumerate_max_slip": "largest number of slip nodes the exhaustive enumeration accepts",
    "settings.enumerate_problems": "problems the enumeration solves (the first is reported as `enumerate`)",
    "settings.mceip_mu_method": "condensed (exact s x s pencil on the slip nodes) or full (full-size MCP)",
    "sweep.mode": "product: every combination; zip: the i-th values together",
    "sweep.parameters": "dotted scene keys (e.g. system.length) -> a list of values or a range "
                        "{start, stop, num} or {start, stop, step}",
    "outputs.paraview": "paraview/states.xdmf (+ .h5) and paraview/modes.vtu (systems with a mesh: block, gmsh)",
    "outputs.plots": "plots/*.png and *.svg (matplotlib)", "outputs.report": "report.md",
    "outputs.states": "the states pictured: an index, final, first_mceip_mu, all_distinct, or node counts "
                      "{stick, slip, free, zero} (the first state with them)",
    "outputs.screenshots": "pyvista off-screen pictures (systems with a mesh: block, gmsh); true: the defaults",
    "outputs.screenshots.resolution": "[width, height] in pixels",
    "outputs.screenshots.field": "colouring of the block", "outputs.screenshots.modes":
        "also draw every divergence mode found at the pictured states",
    "outputs.screenshots.scale": "magnification of the state displacements (modes are scaled to fit)",
    "outputs.screenshots.animate": "also an animated GIF of each mode drawn, growing as a0 exp(lambda t) "
                                   "(lambda^2 > 0), linearly for MCEIP-mu's static mode",
    "refinement.levels": "mesh levels: nx cells along AB (ny = nx * height / length)",
    "refinement.degrees": "Lagrange degrees run at every level", "refinement.planes": "plane models run",
    "refinement.mu_fixed": "mu of the sufficient condition at the final state (null: mceip_lambda2_mu or mu)",
    "refinement.resultant_at": "|CD u_x| of the state whose resultants are compared [length]",
    "refinement.first_solution": "scan: find the first state with an MCEIP-mu solution; none: skip",
    "refinement.max_contact_nodes": "skip levels with more contact nodes (degree * nx + 1)",
}

BOUNDS = (("exclusiveMinimum", "> {}"), ("minimum", ">= {}"), ("exclusiveMaximum", "< {}"), ("maximum", "<= {}"),
          ("minLength", "length >= {}"), ("maxLength", "length <= {}"), ("minItems", "at least {} item(s)"),
          ("maxItems", "at most {} item(s)"))


def _num(v: Any) -> str:
    return json.dumps(v) if not isinstance(v, float) or v != int(v) or abs(v) >= 1e15 else f"{v:g}"


class Schema:
    """The scene's JSON schema and its rendering as markdown tables."""

    def __init__(self, schema: dict):
        self.schema = schema
        self.defs = schema.get("$defs", {})
        self.sections: list[tuple[str, str, dict]] = []    # (path, title, object schema) in order

    def ref(self, s: dict) -> dict:
        """The schema ``s`` points to (``$ref``), or ``s``."""
        return self.defs[s["$ref"].split("/")[-1]] if "$ref" in s else s

    def type_of(self, s: dict, path: str) -> str:
        """Readable type of a field's schema; registers the sections (objects) it contains."""
        if "$ref" in s:
            target = self.ref(s)
            if "properties" in target:
                self.sections.append((path, target.get("title", path), target))
                return f"section ([{path}](#{_anchor(path)}))"
            return self.type_of(target, path)
        if "oneOf" in s and "discriminator" in s:
            tags = []
            for opt in s["oneOf"]:
                target = self.ref(opt)
                tag = target["properties"]["type"].get("const") or target["properties"]["type"]["enum"][0]
                sub = f"{path} (type: {tag})"
                self.sections.append((sub, target.get("title", tag), target))
                tags.append(f"[{tag}](#{_anchor(sub)})")
            return "section, by `type`: " + " or ".join(tags)
        if "anyOf" in s:
            opts = [o for o in s["anyOf"] if o.get("type") != "null"]
            kinds = " or ".join(self.type_of(o, path) for o in opts)
            return kinds + (" or null" if len(opts) < len(s["anyOf"]) else "")
        if "enum" in s or "const" in s:
            vals = s.get("enum", [s.get("const")])
            return "one of " + ", ".join(f"`{_num(v)}`" for v in vals)
        t = s.get("type")
        if t == "array":
            if "prefixItems" in s:
                return "[" + ", ".join(self.type_of(i, path) for i in s["prefixItems"]) + "]"
            return "list of " + self.type_of(s.get("items", {}), path + "[]")
        if t == "object":
            vals = s.get("additionalProperties")
            return "mapping" + (f" of {self.type_of(vals, path)}" if isinstance(vals, dict) and vals else "")
        text = {"number": "number", "integer": "integer", "string": "string", "boolean": "boolean"}.get(t, "any")
        bounds = [fmt.format(_num(s[k])) for k, fmt in BOUNDS if k in s]
        return text + (f" ({', '.join(bounds)})" if bounds else "")

    def table(self, prefix: str, obj: dict) -> list[str]:
        """Markdown rows of one section's keys."""
        rows = ["| key | type and allowed values | default | meaning |", "|---|---|---|---|"]
        required = set(obj.get("required", []))
        for key, s in obj.get("properties", {}).items():
            path = f"{prefix}.{key}" if prefix else key
            base = prefix.split(" (type")[0]
            meaning_key = f"{base}.{key}" if base else key
            typ = self.type_of(s, path)
            if key in required:
                default = "**required**"
            elif "default" in s:
                default = "`" + json.dumps(s["default"]) + "`" if not isinstance(s["default"], dict) else "see the section"
            else:
                default = ""
            meaning = _text(s.get("description") or MEANING.get(meaning_key, ""))
            rows.append(f"| `{key}` | {typ} | {default} | {meaning} |")
        return rows


def _text(s: str) -> str:
    """Schema text for a markdown table cell: one line, ``|`` escaped."""
    return " ".join(s.split()).replace("|", "\\|")


def _anchor(path: str) -> str:
    return "".join(c for c in path.lower().replace(" ", "-") if c.isalnum() or c in "-_")


def generate() -> str:
    """The text of docs/scene-keys.md."""
    from app.scene.schema import Scene
    sch = Schema(Scene.model_json_schema(mode="validation"))
    lines = ["# Scene keys", "",
             "<!-- generated by scripts/scene_keys.py from the pydantic schema (app/scene/schema.py); do not edit -->", "",
             "A scene is a YAML mapping validated by `app.scene.schema.Scene` (`python -m app validate SCENE` checks one; "
             "`app.load_scene` accepts a file or a dictionary). Unknown keys are errors. Units: the scene's `units` "
             "(default mm, N, MPa, tonne, s); mu is dimensionless. The method behind the keys: "
             "[method.md](method.md).", "",
             "## (top level)", ""]
    lines += sch.table("", sch.schema)
    done = 0
    while done < len(sch.sections):
        path, title, obj = sch.sections[done]
        done += 1
        lines += ["", f"## {path}", ""]
        if obj.get("description"):
            lines += [_text(obj["description"]), ""]
        lines += sch.table(path, obj)
    return "\n".join(lines) + "\n"


def main(argv: list[str]) -> int:
    """Write docs/scene-keys.md, or with ``--check`` compare it with the generated text."""
    return write_or_check(OUT, generate(), argv, pathlib.Path(__file__), ROOT)


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main(sys.argv[1:]))
