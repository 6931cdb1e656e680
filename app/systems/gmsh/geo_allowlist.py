"""Check a Gmsh ``.geo`` script against an allowlist before Gmsh sees it.

A ``.geo`` file is a program: Gmsh 4.8 runs ``SystemCall``, writes files with ``Printf(...) >``
and ``Save``, reads any file with ``Merge`` and has no switch that turns this off. A scene's
``.geo`` is therefore read here first, token by token (comments and strings understood), and
refused unless every statement is

* a geometry or meshing command (points, curves, loops, surfaces, physical groups,
  transfinite and size settings, fields, transformations, boolean operations, ``Mesh N``),
* an option of the categories ``Mesh.`` or ``Geometry.``,
* a variable assignment with arithmetic, a ``For`` loop whose bounds, when they can be
  evaluated here, give at most :data:`MAX_ITERATIONS` iterations (nested loops multiply),
  ``If``/``Else``, ``Function``/``Macro``/``Call``,
* ``Printf``/``Error``/``Warning`` to the terminal (not to a file),
* ``Include`` of a file (checked the same way) inside one of the allowed folders.

Anything else, e.g. ``SystemCall``, ``NonBlockingSystemCall``, ``OnelabRun``, ``Save``,
``Merge``, ``Exit``, ``Sleep``, ``Plugin``, ``Print``, options of other categories
(``General.``, ``Solver.``: ``Solver.Executable0`` names a program), is refused with one
:class:`GeoRefused` naming the command and its line. The check is a filter, not a parser: what
passes is still run by Gmsh only in the sandbox of app/systems/gmsh/sandbox.py.
"""
from __future__ import annotations

import math
import pathlib
import re
from dataclasses import dataclass

MAX_ITERATIONS = 1_000_000      # iterations of (nested) For loops whose bounds are known here
MAX_FILE_BYTES = 10 * 2**20     # a larger .geo is refused unread
MAX_INCLUDE_DEPTH = 10

#: commands that start a statement; each is a geometry, meshing or control-flow command
ALLOWED = frozenset("""
Point Line Circle Ellipse Spline BSpline Bezier Nurbs Curve Wire Surface Plane Ruled Volume Compound
Physical Transfinite Recombine Characteristic MeshSize Field Background Mesh Geometry
Translate Rotate Symmetry Dilate Affine Extrude Duplicata Delete Coherence Boundary CombinedBoundary
BooleanUnion BooleanIntersection BooleanDifference BooleanFragments Rectangle Disk Box Sphere Cylinder
Cone Torus Wedge ThruSections Fillet Chamfer HealShapes SetFactory Reverse ReverseMesh Smoother Periodic
Hide Show Color Recursive Split RefineMesh SetOrder OptimizeMesh Printf Error Warning Include
Function Macro Return Call For EndFor If ElseIf Else EndIf DefineConstant DefineNumber DefineString
""".split())

#: refused wherever they appear, with the reason shown
FORBIDDEN = {
    "SystemCall": "runs a program", "NonBlockingSystemCall": "runs a program",
    "OnelabRun": "runs a program", "OnelabAction": "drives ONELAB clients", "SendToServer": "talks to a server",
    "Save": "writes a file", "Print": "writes a file", "Merge": "reads an arbitrary file",
    "MergeWithBoundingBox": "reads an arbitrary file", "ShapeFromFile": "reads an arbitrary file",
    "Exit": "ends the program", "Abort": "ends the program", "Sleep": "waits", "Plugin": "runs a plugin",
    "View": "post-processing views are not geometry", "Combine": "post-processing views are not geometry",
    "Draw": "drives the graphical interface", "SetChanged": "drives the graphical interface",
    "BoxDraw": "drives the graphical interface", "CreateDir": "creates a folder", "DeleteFile": "deletes a file",
    "RenameFile": "renames a file", "GetValue": "reads the terminal", "GetStringValue": "reads the terminal",
    "SetNumber": "changes ONELAB parameters", "SetString": "changes ONELAB parameters",
    "Homology": "writes post-processing data", "Cohomology": "writes post-processing data",
    "Parse": "runs text as code", "NewModel": "replaces the model", "SyncModel": "replaces the model",
}
#: option categories a .geo may set (``Mesh.Algorithm = 6;``); others are refused
OPTION_CATEGORIES = frozenset({"Mesh", "Geometry"})
#: the only words a statement may continue with after a closing brace (``Transfinite Surface {1} = {...} Right;``)
_ASSIGN = {"=", "+=", "-=", "*=", "/=", "++", "--"}
_FUNCTIONS = {"Sqrt": math.sqrt, "Sin": math.sin, "Cos": math.cos, "Tan": math.tan, "Exp": math.exp,
              "Log": math.log, "Fabs": abs, "Abs": abs, "Floor": math.floor, "Ceil": math.ceil,
              "Round": round, "Atan": math.atan, "Asin": math.asin, "Acos": math.acos}

_TOKEN = re.compile(r"""
    (?P<ws>[ \t\r\f\v]+) | (?P<nl>\n) | (?P<line_comment>//[^\n]*) | (?P<block_comment>/\*.*?\*/)
  | (?P<string>"(?:[^"\\\n]|\\.)*") | (?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<ident>[A-Za-z_][A-Za-z0-9_]*) | (?P<op>>>|\+=|-=|\*=|/=|\+\+|--|==|!=|<=|>=|&&|\|\||[^\sA-Za-z0-9_"])
""", re.VERBOSE | re.DOTALL)


class GeoRefused(ValueError):
    """A .geo file the app does not hand to Gmsh; ``str(err)`` is one line naming the command and line."""


@dataclass(frozen=True)
class Token:
    """One token of a .geo text: its kind (``string``, ``number``, ``ident`` or ``op``), its text and
    its line number."""

    kind: str       # string, number, ident, op
    text: str
    line: int


def tokens(text: str, name: str) -> list[Token]:
    """The tokens of a .geo text (comments and blanks dropped), each with its line number."""
    out, line, pos = [], 1, 0
    while pos < len(text):
        if text.startswith("/*", pos) and text.find("*/", pos + 2) < 0:
            raise GeoRefused(f"{name} line {line}: a comment /* is never closed")
        m = _TOKEN.match(text, pos)
        if m is None:
            if text[pos] == '"':
                raise GeoRefused(f"{name} line {line}: a string is never closed")
            raise GeoRefused(f"{name} line {line}: unexpected character {text[pos]!r}")
        kind, value = m.lastgroup, m.group()
        if kind in ("string", "number", "ident", "op"):
            out.append(Token(kind, value, line))
        line += value.count("\n")
        pos = m.end()
    return out


def _opens(t: Token) -> bool:
    return t.kind == "op" and t.text in ("(", "[", "{")


def _closes(t: Token) -> bool:
    return t.kind == "op" and t.text in (")", "]", "}")


def _statements(toks: list[Token]):
    """Split tokens into statements: up to a ``;`` outside brackets, or a closing brace at depth 0
    followed by a word that starts a statement (``Rotate {...} { Surface{1}; }`` has no ``;``);
    control words (For, If, EndFor, ...) are statements of their own with their head."""
    i, n = 0, len(toks)
    while i < n:
        t = toks[i]
        if t.kind == "ident" and t.text in ("EndFor", "EndIf", "Else", "Return"):
            yield toks[i:i + 1]
            i += 1 + (i + 1 < n and toks[i + 1].text == ";")
            continue
        if t.kind == "ident" and t.text in ("Function", "Macro"):
            yield toks[i:i + 2]
            i += 2
            continue
        if t.kind == "ident" and t.text in ("For", "If", "ElseIf"):
            j = i + 1
            if j < n and toks[j].kind == "ident":        # For i In {a:b}
                j += 2
            depth = 0
            while j < n:
                if _opens(toks[j]):
                    depth += 1
                elif _closes(toks[j]):
                    depth -= 1
                    if depth <= 0:
                        j += 1
                        break
                j += 1
            yield toks[i:j]
            i = j
            continue
        depth, j = 0, i
        while j < n:
            tx = toks[j].text
            if _opens(toks[j]):
                depth += 1
            elif _closes(toks[j]):
                depth = max(depth - 1, 0)
                if (depth == 0 and tx == "}" and j + 1 < n and toks[j + 1].kind == "ident"
                        and (toks[j + 1].text in ALLOWED or toks[j + 1].text in FORBIDDEN)):
                    j += 1
                    break
            elif toks[j].kind == "op" and tx == ";" and depth == 0:
                j += 1
                break
            j += 1
        yield toks[i:j]
        i = j


class _Evaluator:
    """Numbers of simple expressions (literals, + - * / ^ %, parentheses, known scalar variables,
    Pi and a few functions); None when an expression is beyond it."""

    def __init__(self):
        self.vars: dict[str, float] = {}

    def value(self, toks: list[Token]) -> float | None:
        self.toks, self.pos = toks, 0
        try:
            v = self._sum()
        except (ArithmeticError, ValueError, IndexError, KeyError, TypeError, OverflowError):
            return None
        return v if self.pos == len(toks) and v is not None and math.isfinite(v) else None

    def _peek(self) -> str | None:
        return self.toks[self.pos].text if self.pos < len(self.toks) else None

    def _sum(self):
        v = self._product()
        while self._peek() in ("+", "-"):
            op = self.toks[self.pos].text
            self.pos += 1
            w = self._product()
            v = v + w if op == "+" else v - w
        return v

    def _product(self):
        v = self._power()
        while self._peek() in ("*", "/", "%"):
            op = self.toks[self.pos].text
            self.pos += 1
            w = self._power()
            v = v * w if op == "*" else (v / w if op == "/" else math.fmod(v, w))
        return v

    def _power(self):
        v = self._unary()
        if self._peek() == "^":
            self.pos += 1
            v = v ** self._power()
        return v

    def _unary(self):
        if self._peek() == "-":
            self.pos += 1
            return -self._unary()
        if self._peek() == "+":
            self.pos += 1
            return self._unary()
        t = self.toks[self.pos]
        self.pos += 1
        if t.kind == "number":
            return float(t.text)
        if t.text == "(":
            v = self._sum()
            if self._peek() != ")":
                raise ValueError
            self.pos += 1
            return v
        if t.kind == "ident" and t.text == "Pi":
            return math.pi
        if t.kind == "ident" and t.text in _FUNCTIONS and self._peek() in ("[", "("):
            close = "]" if self._peek() == "[" else ")"
            self.pos += 1
            v = self._sum()
            if self._peek() != close:
                raise ValueError
            self.pos += 1
            return float(_FUNCTIONS[t.text](v))
        if t.kind == "ident" and t.text in self.vars and self._peek() not in ("[", "(", "."):
            return self.vars[t.text]
        raise ValueError


def _loop_count(head: list[Token], ev: _Evaluator) -> float | None:
    """Iterations of ``For (a:b:c)`` / ``For i In {a:b:c}``, None when the bounds are unknown here."""
    body = head[1:]
    if body and body[0].kind == "ident":
        body = body[2:]                                   # i In
    if len(body) < 2 or not _opens(body[0]) or not _closes(body[-1]):
        return None
    inner = body[1:-1]
    parts, depth, cur = [], 0, []
    for t in inner:
        depth += _opens(t) - _closes(t)
        if t.text == ":" and depth == 0:
            parts.append(cur)
            cur = []
        else:
            cur.append(t)
    parts.append(cur)
    if len(parts) not in (2, 3):
        return None
    vals = [ev.value(p) for p in parts]
    if any(v is None for v in vals):
        return None
    a, b = vals[0], vals[1]
    step = vals[2] if len(parts) == 3 else 1.0
    if step == 0:
        return math.inf
    return max(0.0, math.floor((b - a) / step + 1e-9) + 1)


@dataclass
class _Context:
    roots: tuple[pathlib.Path, ...]
    seen: tuple[pathlib.Path, ...] = ()


def check_file(path: pathlib.Path, roots: tuple[pathlib.Path, ...] | None = None, _ctx: _Context | None = None,
               _ev: _Evaluator | None = None) -> None:
    """Raise :class:`GeoRefused` unless ``path`` (and every file it includes) passes the allowlist.

    ``roots``: folders an ``Include`` may name files in (default: the folder of ``path``).
    """
    path = pathlib.Path(path).resolve()
    ctx = _ctx or _Context(roots=tuple(pathlib.Path(r).resolve() for r in (roots or (path.parent,))))
    ev = _ev or _Evaluator()
    name = path.name
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as err:
        raise GeoRefused(f"cannot read {name}: {err.strerror or err}") from None
    if len(data) > MAX_FILE_BYTES:
        raise GeoRefused(f"{name} has more than {MAX_FILE_BYTES} bytes: too large for a geometry script")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise GeoRefused(f"{name}: not UTF-8 text (byte at offset {err.start}): a .geo must be a text file") from None
    if "\0" in text:
        raise GeoRefused(f"{name}: contains a NUL byte: a .geo must be a text file")
    check_text(text, name, path.parent, ctx, ev)


def check_text(text: str, name: str, folder: pathlib.Path, ctx: _Context, ev: _Evaluator) -> None:
    """Check the statements of one .geo text (see the module docstring)."""
    toks = tokens(text, name)
    loops: list[float] = []          # iterations of the enclosing For loops (1 when unknown)
    for st in _statements(toks):
        first = st[0]
        where = f"{name} line {first.line}"
        for k, t in enumerate(st):
            if t.kind != "ident":
                continue
            if t.text in FORBIDDEN:
                raise GeoRefused(f"{name} line {t.line}: '{t.text}' is not allowed in a .geo file "
                                 f"({FORBIDDEN[t.text]}); only geometry and meshing commands are")
            if (k + 1 < len(st) and st[k + 1].text == "." and t.text not in OPTION_CATEGORIES
                    and not (k > 0 and st[k - 1].text == ".")):
                raise GeoRefused(f"{name} line {t.line}: the option '{t.text}.{st[k + 2].text if k + 2 < len(st) else ''}' "
                                 f"is not allowed in a .geo file: only Mesh.* and Geometry.* options are")
        word = first.text
        if first.kind == "ident" and word == "For":
            count = _loop_count(st, ev)
            total = math.prod(loops) * (count if count is not None else 1)
            if total > MAX_ITERATIONS:
                raise GeoRefused(f"{where}: a For loop of {total:.3g} iterations (with the enclosing loops): at most "
                                 f"{MAX_ITERATIONS} are allowed in a .geo file")
            loops.append(count if count is not None else 1)
            continue
        if first.kind == "ident" and word == "EndFor":
            if loops:
                loops.pop()
            continue
        if first.kind == "ident" and word == "Include":
            _include(st, where, folder, ctx, ev)
            continue
        if first.kind == "ident" and word == "Printf":
            depth = 0
            for t in st:
                depth += _opens(t) - _closes(t)
                if depth == 0 and t.text in (">", ">>"):
                    raise GeoRefused(f"{where}: 'Printf' to a file is not allowed in a .geo file (it writes a file); "
                                     "Printf to the terminal is")
            continue
        if first.kind == "ident" and word in ALLOWED:
            continue
        if first.kind == "ident":
            if any(t.text in _ASSIGN for t in st[1:]):
                _remember(st, ev, inside_loop=bool(loops))
                continue
            raise GeoRefused(f"{where}: '{word}' is not an allowed .geo command: only geometry and meshing commands, "
                             "Mesh.*/Geometry.* options, variables and bounded loops are")
        if first.text == ";":
            continue
        raise GeoRefused(f"{where}: a statement cannot start with {first.text!r}")


def _remember(st: list[Token], ev: _Evaluator, inside_loop: bool) -> None:
    """Track ``name = expr;`` of a scalar for the loop bounds (forgotten when assigned in a loop)."""
    name = st[0].text
    if inside_loop or len(st) < 3 or st[1].text != "=":
        ev.vars.pop(name, None)
        return
    expr = st[2:-1] if st[-1].text == ";" else st[2:]
    v = ev.value(expr)
    if v is None:
        ev.vars.pop(name, None)
    else:
        ev.vars[name] = v


def _include(st: list[Token], where: str, folder: pathlib.Path, ctx: _Context, ev: _Evaluator) -> None:
    """``Include "file";``: a plain string naming a file inside the allowed folders, checked recursively."""
    args = [t for t in st[1:] if t.text != ";"]
    if len(args) != 1 or args[0].kind != "string":
        raise GeoRefused(f"{where}: 'Include' needs one plain file name in quotes")
    raw = args[0].text[1:-1]
    target = (folder / raw).resolve()
    if not any(target == r or r in target.parents for r in ctx.roots):
        raise GeoRefused(f"{where}: 'Include \"{raw}\"' names a file outside the scene's folder: not allowed")
    if target in ctx.seen or len(ctx.seen) >= MAX_INCLUDE_DEPTH:
        raise GeoRefused(f"{where}: 'Include \"{raw}\"' includes itself or nests more than {MAX_INCLUDE_DEPTH} deep")
    if not target.is_file():
        raise GeoRefused(f"{where}: 'Include \"{raw}\"': no such file")
    check_file(target, None, _Context(roots=ctx.roots, seen=ctx.seen + (target,)), ev)
