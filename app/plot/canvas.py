"""The pyvista canvas of the screenshots (app/plot/screenshots.py): the data of
``fields/fields.npz``, one reused off-screen plotter per resolution, and the parts of a picture
(the body, its outline, the obstacle, the contact-node markers, the title lines and legend, the
colour bar, the camera)."""
from __future__ import annotations

import json
import os
import pathlib
import typing

import numpy as np

MARKERS = {  # legend label, colour
    "stick": ("stick", "#1f77b4"),
    "slip": ("slip (impending)", "#d62728"),
    "slip_mode": ("slip node, slips in the mode", "#d62728"),
    "stuck_mode": ("slip node, stuck in the mode", "#111111"),
    "free": ("free (no contact)", "#9a9a9a"),
    "zero": ("zero reaction", "#9467bd"),
}

def import_pyvista():
    """pyvista, set to draw off screen (with EGL when there is no display, so that VTK neither tries X
    first nor warns)."""
    # Off screen, with no X server: pick EGL directly when there is no display (VTK would try X first
    # and print a warning before falling back).
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv
    pv.OFF_SCREEN = True
    return pv


#: a mode is drawn with its largest displacement at most this fraction of the body's smaller side,
MODE_SIDE = 0.12
#: and no edge of the mesh changed by more than this fraction of its length
MODE_EDGE = 0.3


class FieldData:
    """The content of fields/fields.npz."""

    def __init__(self, path: "pathlib.Path | typing.BinaryIO"):
        with np.load(path, allow_pickle=False) as z:
            self.points = z["points"]
            self.cells = z["cells"]
            self.cell_type = str(z["cell_type"])
            self.contact = z["contact_points"]
            self.state_index = [int(i) for i in z["state_index"]]
            self.state_u = z["state_u"]
            self.state_vm = z["state_von_mises"]
            self.mode_v = z["mode_v"]
            self.modes = json.loads(str(z["modes_json"]))
            files = set(z.files)
            self.obstacle = None        # (point, outward normal of the body), None: no obstacle line
            self.circle = None          # (centre, radius, +1 body outside / -1 inside): a circle obstacle
            if "obstacle_circle" in files:
                oc = z["obstacle_circle"].astype(float)
                self.circle = (oc[:2], float(oc[2]), float(oc[3]))
            self.polyline = z["obstacle_polyline"].astype(float) if "obstacle_polyline" in files else None
            if "obstacle_point" in files:
                self.obstacle = (z["obstacle_point"].astype(float), z["obstacle_normal"].astype(float))
            elif "length_scale" not in files and self.polyline is None:      # written before the geometry keys: the block on y = 0
                self.obstacle = (np.zeros(2), np.array([0.0, -1.0]))
        lo, hi = self.points.min(axis=0), self.points.max(axis=0)
        self.width, self.height = (float(v) for v in (hi - lo))
        self.size = max(self.width, self.height)          # the body's extent
        self.small = min(self.width, self.height) or self.size   # its smaller side (mode amplitude, strip depth)

    def grid(self, displacement: np.ndarray):
        """The body as a pyvista grid of its P1 or P2 triangles (z = 0), each point moved by its row of
        ``displacement`` (already scaled for the drawing)."""
        pv = import_pyvista()
        vtk_type = pv.CellType.TRIANGLE if self.cell_type == "triangle" else pv.CellType.QUADRATIC_TRIANGLE
        k = self.cells.shape[1]
        conn = np.hstack([np.full((len(self.cells), 1), k), self.cells]).ravel()
        pts = np.column_stack([self.points + displacement, np.zeros(len(self.points))])
        return pv.UnstructuredGrid(conn, np.full(len(self.cells), vtk_type, dtype=np.uint8), pts)

    def edges(self) -> np.ndarray:
        """The mesh's edges between cell corners, ``(E, 2)`` point indices, each once (computed once)."""
        if getattr(self, "_edges", None) is None:
            tri = self.cells[:, :3]          # a P2 triangle's corners come first (VTK order)
            e = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
            self._edges = np.unique(e, axis=0)
        return self._edges

    def element_size(self) -> float:
        """The element size h: the median length of the mesh's edges."""
        e = self.edges()
        return float(np.median(np.linalg.norm(self.points[e[:, 0]] - self.points[e[:, 1]], axis=1)))

    def mode_amplitude(self, v: np.ndarray) -> float:
        """How large to draw the mode ``v`` (max |v| = 1): its largest displacement at most
        :data:`MODE_SIDE` of the body's smaller side, and small enough that no edge of the mesh
        changes by more than :data:`MODE_EDGE` of its length (the displacement difference of its
        two ends): a slipping node is never drawn past its stuck neighbour, the mesh never folds."""
        e = self.edges()
        length = np.linalg.norm(self.points[e[:, 0]] - self.points[e[:, 1]], axis=1)
        jump = np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)
        moving = jump > 0
        fold = MODE_EDGE * float(np.min(length[moving] / jump[moving])) if moving.any() else np.inf
        return min(MODE_SIDE * self.small, fold)

    def mode(self, name: str) -> np.ndarray:
        """The displacement of the mode named ``name`` at every point, shape (N, 2), normalised to
        max |v| = 1."""
        names = [m["name"] for m in self.modes]
        return self.mode_v[names.index(name)]


def truetype_font() -> str | None:
    """A TrueType font with the symbols used (matplotlib's DejaVu Sans), or None for VTK's own."""
    try:
        from matplotlib import font_manager
        return font_manager.findfont("DejaVu Sans", fallback_to_default=False)
    except Exception:
        return None


_PLOTTERS: dict[tuple[int, int], object] = {}


def plotter(res: tuple[int, int]):
    """The off-screen plotter of this resolution, emptied (one plotter, one OpenGL
    context and its compiled shaders for every picture instead of one per picture; lights, the
    background and the window are kept). :func:`close_plotters` releases them."""
    res = (int(res[0]), int(res[1]))
    pl = _PLOTTERS.get(res)
    if pl is None:
        pv = import_pyvista()
        pl = pv.Plotter(off_screen=True, window_size=list(res))
        pl.set_background("white")
        _PLOTTERS[res] = pl
    else:
        for title in list(pl.scalar_bars.keys()):
            pl.remove_scalar_bar(title, render=False)
        pl.renderer.clear_actors()
    pl.suppress_rendering = True          # no intermediate renders while the scene is built
    return pl


def close_plotters() -> None:
    """Close the plotters kept by :func:`plotter`."""
    while _PLOTTERS:
        _PLOTTERS.popitem()[1].close()


def font_size(res) -> int:
    """Font size in points for a picture of ``res`` pixels: 11 at 1000 x 640, scaled by the smaller
    of the two ratios, at least 8."""
    return max(8, int(round(11 * min(res[0] / 1000, res[1] / 640))))


def _obstacle(pl, fd: FieldData, pts: np.ndarray) -> np.ndarray:
    """The rigid obstacle: a grey hatched strip along its line, on the side of the body's outward
    normal, as long as the body's projection on the line plus margins; returns its corners (x, y)."""
    if fd.circle is not None:
        return _circle_obstacle(pl, fd, pts)
    if fd.polyline is not None:
        return _curve_obstacle(pl, fd, pts)
    if fd.obstacle is None:
        return np.zeros((0, 2))
    pv = import_pyvista()
    p, n = fd.obstacle
    n = n / np.linalg.norm(n)
    t = np.array([-n[1], n[0]])
    s = np.concatenate([(pts - p) @ t, (fd.points - p) @ t])
    margin = 0.06 * fd.size
    s0, s1 = float(s.min()) - margin, float(s.max()) + margin
    depth = 0.08 * fd.small

    def at(a: float, b: float) -> list[float]:        # point a along t, b along n (into the obstacle)
        q = p + a * t + b * n
        return [float(q[0]), float(q[1])]

    corners = np.array([at(s0, depth), at(s1, depth), at(s1, 0.0), at(s0, 0.0)])
    rect = pv.Rectangle([[*corners[0], -0.02], [*corners[1], -0.02], [*corners[2], -0.02]])
    pl.add_mesh(rect, color="#9a9a9a")
    hatch = []
    a = s0
    while a + depth <= s1:
        hatch += [[*at(a, depth), -0.01], [*at(a + depth, 0.0), -0.01]]
        a += (s1 - s0) / 40
    if hatch:
        k = len(hatch) // 2
        lines = np.column_stack([np.full(k, 2), 2 * np.arange(k), 2 * np.arange(k) + 1]).ravel()
        pl.add_mesh(pv.PolyData(np.array(hatch), lines=lines), color="#5f5f5f", line_width=1)
    pl.add_mesh(pv.Line((*at(s0, 0.0), -0.015), (*at(s1, 0.0), -0.015)), color="#5f5f5f", line_width=1.5)
    return corners


def _circle_obstacle(pl, fd: FieldData, pts: np.ndarray) -> np.ndarray:
    """A circle obstacle: a grey hatched band along the arc the body faces (inside the circle when
    the body is outside it, outside in a bore), over the body's angular extent plus margins;
    returns the band's outline points (x, y)."""
    pv = import_pyvista()
    c, R, sign = fd.circle
    d = np.concatenate([pts, fd.points]) - c
    mid = np.arctan2(*np.mean(d, axis=0)[::-1])
    th = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - mid)))
    margin = 0.06 * fd.size / R
    t0, t1 = float(th.min()) - margin, float(th.max()) + margin
    depth = min(0.08 * fd.small, 0.5 * R)
    r_in, r_out = (R - depth, R) if sign > 0 else (R, R + depth)
    ang = mid + np.linspace(t0, t1, 97)
    ring = lambda r: np.column_stack([c[0] + r * np.cos(ang), c[1] + r * np.sin(ang)])   # noqa: E731
    outline = np.concatenate([ring(r_out), ring(r_in)[::-1]])
    face = pv.PolyData(np.column_stack([outline, np.full(len(outline), -0.02)]),
                       faces=np.concatenate([[len(outline)], np.arange(len(outline))]))
    pl.add_mesh(face.triangulate(), color="#9a9a9a")
    surface = ring(R)
    k = 40
    hatch = []
    for j in range(0, len(ang) - 1, max(1, len(ang) // k)):
        a = ang[min(j + 2, len(ang) - 1)]
        p_far = c + (r_in if sign > 0 else r_out) * np.array([np.cos(ang[j]), np.sin(ang[j])])
        p_on = c + R * np.array([np.cos(a), np.sin(a)])
        hatch += [[*p_far, -0.01], [*p_on, -0.01]]
    if hatch:
        m = len(hatch) // 2
        lines = np.column_stack([np.full(m, 2), 2 * np.arange(m), 2 * np.arange(m) + 1]).ravel()
        pl.add_mesh(pv.PolyData(np.array(hatch), lines=lines), color="#5f5f5f", line_width=1)
    line = pv.lines_from_points(np.column_stack([surface, np.full(len(surface), -0.015)]))
    pl.add_mesh(line, color="#5f5f5f", line_width=1.5)
    return outline


def _curve_obstacle(pl, fd: FieldData, pts: np.ndarray) -> np.ndarray:
    """A curve obstacle: its points within the body's extent (plus margins) as a grey line;
    returns them (x, y)."""
    pv = import_pyvista()
    c = fd.polyline
    lo = np.minimum(pts.min(axis=0), fd.points.min(axis=0)) - 0.3 * fd.size
    hi = np.maximum(pts.max(axis=0), fd.points.max(axis=0)) + 0.3 * fd.size
    keep = np.all((c >= lo) & (c <= hi), axis=1)
    c = c[keep] if np.sum(keep) >= 2 else c
    line = pv.lines_from_points(np.column_stack([c, np.full(len(c), -0.015)]))
    pl.add_mesh(line, color="#5f5f5f", line_width=3)
    return c


def _edges(fd: FieldData, displacement: np.ndarray | None = None, boundary: bool = False):
    """Mesh edges as lines (through the mid-side node of a quadratic cell): all of them, or the
    boundary ones (edges of one cell only); on the displaced points if given."""
    pv = import_pyvista()
    c = fd.cells
    if c.shape[1] == 6:        # VTK quadratic triangle: vertices 0 1 2, mid-sides 3 (01) 4 (12) 5 (20)
        edges = np.concatenate([c[:, [0, 3, 1]], c[:, [1, 4, 2]], c[:, [2, 5, 0]]])
    else:
        edges = np.concatenate([c[:, [0, 1]], c[:, [1, 2]], c[:, [2, 0]]])
    key = np.sort(edges[:, [0, -1]], axis=1)
    _, first, inv, count = np.unique(key, axis=0, return_index=True, return_inverse=True, return_counts=True)
    edges = edges[count[inv.ravel()] == 1] if boundary else edges[first]
    k = edges.shape[1]
    lines = np.column_stack([np.full(len(edges), k), edges]).ravel()
    xy = fd.points if displacement is None else fd.points + displacement
    return pv.PolyData(np.column_stack([xy, np.full(len(xy), 0.01)]), lines=lines)


def _outline(fd: FieldData):
    """Boundary of the undeformed body: the mesh edges that belong to one cell only."""
    return _edges(fd, boundary=True)


def add_body(pl, fd: FieldData, grid, displacement: np.ndarray, **kw) -> None:
    """The coloured mesh with its cell edges (a quadratic cell's curved edges, not VTK's subdivision)."""
    quadratic = fd.cells.shape[1] == 6
    pl.add_mesh(grid, show_edges=not quadratic, edge_color="#303030", line_width=0.5, **kw)
    if quadratic:
        pl.add_mesh(_edges(fd, displacement), color="#303030", line_width=0.5)


def markers(pl, pts: np.ndarray, groups: dict[str, list[int]], size: float) -> list[tuple[str, str]]:
    """Contact nodes as coloured spheres; returns the legend entries used."""
    used = []
    for key, ids in groups.items():
        if not ids:
            continue
        label, colour = MARKERS[key]
        xyz = np.column_stack([pts[ids], np.full(len(ids), 0.05)])
        pl.add_points(xyz, color=colour, point_size=size, render_points_as_spheres=True)
        used.append((label, colour))
    return used


def text(pl, text: str, x: float, y: float, size: int, colour: str = "black") -> None:
    """Write ``text`` at ``(x, y)`` in viewport coordinates (0 to 1) in ``size`` points, in the
    TrueType font when there is one (:func:`truetype_font`)."""
    font = truetype_font()
    kw = {"font_file": font} if font else {}
    pl.add_text(text, position=(x, y), viewport=True, font_size=size, color=colour, **kw)


def finish(pl, fd: FieldData, pts: np.ndarray, title: list[str], legend: list[tuple[str, str]],
            path: pathlib.Path, res, extent: np.ndarray | None = None) -> pathlib.Path:
    """Obstacle, outline, title lines and legend row at the top, camera, screenshot. ``extent``:
    the points the view must hold (default ``pts``; the frames of an animation give the largest
    displacement's, so that the camera stays still)."""
    pts = pts if extent is None else np.vstack([pts, extent])
    strip = _obstacle(pl, fd, pts)
    pl.add_mesh(_outline(fd), color="#666666", line_width=1.5, style="wireframe")
    seen = np.vstack([pts, fd.points, strip])
    xmin = float(seen[:, 0].min()) - (0.0 if len(strip) else 0.06 * fd.size)
    xmax = float(seen[:, 0].max()) + (0.0 if len(strip) else 0.06 * fd.size)
    fs = font_size(res)
    line = 1.9 * fs / res[1]                      # one text line, as a fraction of the height
    char = 1.0 * fs / res[0]                      # mean character width (DejaVu Sans), fraction of the width
    y = 1.0 - 0.012 - line * 1.2
    text(pl, title[0], 0.012, y, int(round(fs * 1.2)))
    for t in title[1:]:
        for part in _wrap(t, int(0.97 / char)):
            y -= line
            text(pl, part, 0.012, y, fs)
    y -= line
    x = 0.012
    for label, colour in legend:
        entry = ("\u25cf " if truetype_font() else "o ") + label
        width = (len(entry) + 3) * char
        if x > 0.012 and x + width > 0.99:        # next legend row
            x, y = 0.012, y - line
        text(pl, entry, x, y, fs, colour)
        x += width
    top_band = 1.0 - (y - 0.02)                   # fraction of the picture used by the text at the top
    pl.view_xy()
    pl.enable_parallel_projection()
    ymin, ymax = float(seen[:, 1].min()), float(seen[:, 1].max())
    band = max(0.3, 1.0 - top_band - 0.17)        # free band between the text and the colour bar
    aspect = res[0] / res[1]
    height = max((ymax - ymin) / band, (xmax - xmin) / (0.97 * aspect))
    # place [ymin, ymax] in the middle of the free band
    v_mid = 0.17 + 0.5 * band
    cx = 0.5 * (xmin + xmax)
    cy = 0.5 * (ymin + ymax) + (0.5 - v_mid) * height
    cam = pl.camera
    cam.focal_point = (cx, cy, 0.0)
    cam.position = (cx, cy, 10.0 * fd.size)
    cam.up = (0.0, 1.0, 0.0)
    cam.parallel_scale = 0.5 * height
    path.parent.mkdir(parents=True, exist_ok=True)
    pl.suppress_rendering = False
    pl.render()                 # a reused plotter: render this scene (the first screenshot renders itself)
    from PIL import Image
    # the same pixels as pl.screenshot(path); zlib level 1: 1.5x faster to write, 14 % larger
    Image.fromarray(pl.screenshot(None, return_img=True)).save(path, format="PNG", compress_level=1)
    return path


def _wrap(text: str, width: int) -> list[str]:
    """A long line as lines of at most ``width`` characters, broken at '; ' first, then at spaces."""
    import textwrap
    if len(text) <= width:
        return [text]
    out = []
    for phrase in text.split("; "):
        out += textwrap.wrap(phrase, width) or [""]
    return out


def bar_args(title: str, fmt: str, res) -> dict:
    """Keyword arguments of pyvista's horizontal colour bar titled ``title`` at the bottom centre,
    labels formatted by ``fmt``, fonts scaled with the resolution (:func:`font_size`)."""
    fs = font_size(res)
    return {"title": title, "vertical": False, "position_x": 0.25, "position_y": 0.02, "width": 0.5,
            "height": 0.08, "color": "black", "fmt": fmt, "title_font_size": int(fs * 2.1),
            "label_font_size": int(fs * 1.9), "unconstrained_font_size": True, "n_labels": 5}
