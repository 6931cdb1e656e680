"""Draw docs/block.svg: the paper's block with its corners A, B, C, D, the axes and the loading.

    python docs/block_figure.py      # rewrites docs/block.svg (tests/test_docs.py checks it is current)

Plain SVG text, no plotting library: the figure is a few rectangles, lines and labels.
"""
from __future__ import annotations

import pathlib

L, H = 80.0, 40.0          # mm (the default scene)
NX = 20                    # cells along AB: 21 contact nodes
S = 7.0                    # px per mm
X0, Y0 = 90.0, 100.0       # top-left corner D of the block, px


def px(x: float, y: float) -> tuple[float, float]:
    """Picture coordinates of the block point (x, y) [mm] (y up, A at the origin)."""
    return X0 + S * x, Y0 + S * (H - y)


def svg() -> str:
    """The figure's SVG text."""
    ax, ay = px(0, 0)
    bx, by = px(L, 0)
    cx, cy = px(L, H)
    dx, dy = px(0, H)
    w, h = S * L, S * H
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{X0 + w + 190:.0f}" height="{ay + 120:.0f}" '
           'font-family="DejaVu Sans, Arial, sans-serif" font-size="15">',
           '<title>The block of Villechaise and Zeghloul: corners A, B, C, D, axes x, y, contact directions '
           'T, N and the loading</title>',
           '<defs><marker id="arrow" viewBox="0 0 10 10" refX="9" refY="5" markerWidth="7" markerHeight="7" '
           'orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" fill="context-stroke"/></marker>',
           '<pattern id="hatch" width="10" height="10" patternUnits="userSpaceOnUse" '
           'patternTransform="rotate(45)"><line x1="0" y1="0" x2="0" y2="10" stroke="#777" stroke-width="2"/>'
           '</pattern></defs>',
           # obstacle
           f'<rect x="{ax - 40:.1f}" y="{ay:.1f}" width="{w + 80:.1f}" height="22" fill="url(#hatch)"/>',
           f'<line x1="{ax - 40:.1f}" y1="{ay:.1f}" x2="{bx + 40:.1f}" y2="{by:.1f}" stroke="#333" stroke-width="2"/>',
           f'<text x="{bx + 45:.1f}" y="{ay + 17:.1f}" fill="#444">rigid flat obstacle</text>',
           # block and a few mesh lines (20 x 10 square cells of 4 mm)
           f'<rect x="{dx:.1f}" y="{dy:.1f}" width="{w:.1f}" height="{h:.1f}" fill="#e8eef7" stroke="#1f3b63" '
           'stroke-width="2.5"/>']
    for i in range(1, NX):
        x, _ = px(L * i / NX, 0)
        out.append(f'<line x1="{x:.1f}" y1="{dy:.1f}" x2="{x:.1f}" y2="{ay:.1f}" stroke="#c5d2e6" stroke-width="0.8"/>')
    for j in range(1, 10):
        _, y = px(0, H * j / 10)
        out.append(f'<line x1="{dx:.1f}" y1="{y:.1f}" x2="{cx:.1f}" y2="{y:.1f}" stroke="#c5d2e6" stroke-width="0.8"/>')
    # contact nodes on AB
    for i in range(NX + 1):
        x, y = px(L * i / NX, 0)
        out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="3.2" fill="#d62728"/>')
    # corners
    for name, (x, y), (ox, oy) in (("A", (ax, ay), (-22, 22)), ("B", (bx, by), (8, 22)),
                                   ("C", (cx, cy), (8, -8)), ("D", (dx, dy), (-22, -8))):
        out.append(f'<text x="{x + ox:.1f}" y="{y + oy:.1f}" font-size="20" font-weight="bold">{name}</text>')
    # axes at A
    out += [f'<line x1="{ax:.1f}" y1="{ay:.1f}" x2="{ax + 70:.1f}" y2="{ay:.1f}" stroke="#000" stroke-width="2" '
            'marker-end="url(#arrow)"/>',
            f'<text x="{ax + 62:.1f}" y="{ay - 8:.1f}" font-style="italic">x</text>',
            f'<line x1="{ax:.1f}" y1="{ay:.1f}" x2="{ax:.1f}" y2="{ay - 70:.1f}" stroke="#000" stroke-width="2" '
            'marker-end="url(#arrow)"/>',
            f'<text x="{ax + 8:.1f}" y="{ay - 60:.1f}" font-style="italic">y</text>']
    # contact directions at a node of AB: T = +x, N = outward normal = -y
    tx, ty = px(L * 0.25, 0)
    out += [f'<line x1="{tx:.1f}" y1="{ty:.1f}" x2="{tx + 50:.1f}" y2="{ty:.1f}" stroke="#2ca02c" stroke-width="2.5" '
            'marker-end="url(#arrow)"/>',
            f'<text x="{tx + 40:.1f}" y="{ty - 8:.1f}" fill="#2ca02c" font-weight="bold">T</text>',
            f'<line x1="{tx:.1f}" y1="{ty:.1f}" x2="{tx:.1f}" y2="{ty + 50:.1f}" stroke="#2ca02c" stroke-width="2.5" '
            'marker-end="url(#arrow)"/>',
            f'<text x="{tx + 8:.1f}" y="{ty + 48:.1f}" fill="#2ca02c" font-weight="bold">N</text>',
            f'<text x="{tx + 30:.1f}" y="{ty + 75:.1f}" fill="#2ca02c" font-size="13">T = +x, N = -y (outward normal '
            'of AB)</text>']
    # loading of CD: pressed down, then dragged to the left
    mx, my = px(L / 2, H)
    out += [f'<line x1="{mx:.1f}" y1="{my - 50:.1f}" x2="{mx:.1f}" y2="{my - 4:.1f}" stroke="#9467bd" '
            'stroke-width="2.5" marker-end="url(#arrow)"/>',
            f'<text x="{mx + 8:.1f}" y="{my - 32:.1f}" fill="#9467bd">1. press CD down (normal resultant 55 N)</text>',
            f'<line x1="{mx - 30:.1f}" y1="{my - 14:.1f}" x2="{mx - 110:.1f}" y2="{my - 14:.1f}" stroke="#9467bd" '
            'stroke-width="2.5" marker-end="url(#arrow)"/>',
            f'<text x="{dx:.1f}" y="{my - 56:.1f}" fill="#9467bd">2. drag CD to the left (u_x &lt; 0)</text>',
            # dimensions
            f'<text x="{(ax + bx) / 2 + 10:.1f}" y="{ay + 45:.1f}">L = 80 mm (AB, 21 contact nodes)</text>',
            f'<text x="{cx + 12:.1f}" y="{(cy + by) / 2:.1f}">H = 40 mm</text>',
            f'<text x="{cx + 12:.1f}" y="{(cy + by) / 2 + 20:.1f}" font-size="13">thickness 9.6 mm</text>',
            '</svg>']
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    path = pathlib.Path(__file__).with_name("block.svg")
    path.write_text(svg(), encoding="utf-8")
    print(f"wrote {path}")
