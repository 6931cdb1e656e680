"""A mode is drawn as large as the mesh allows without folding (issue 35): its largest
displacement at most 12 % of the body's smaller side and no edge changed by more than 30 % of its
length, so that a slipping node is never drawn past its stuck neighbour; the picture states the
scale against the element size. Checked on a small mesh with exact answers."""
import numpy as np

from app.plot.canvas import MODE_EDGE, MODE_SIDE, FieldData


def _fields(tmp_path, nx=8, ny=4, length=80.0, height=40.0) -> FieldData:
    """A structured triangle mesh of a length x height block, written as fields.npz."""
    x, y = np.meshgrid(np.linspace(0, length, nx + 1), np.linspace(0, height, ny + 1))
    points = np.column_stack([x.ravel(), y.ravel()])
    cells = []
    for j in range(ny):
        for i in range(nx):
            a, b = j * (nx + 1) + i, j * (nx + 1) + i + 1
            c, d = a + nx + 1, b + nx + 1
            cells += [[a, b, d], [a, d, c]]
    path = tmp_path / "fields.npz"
    np.savez(path, points=points, cells=np.array(cells), cell_type="triangle", contact_points=np.arange(nx + 1),
             state_index=np.zeros(0, int), state_u=np.zeros((0, len(points), 2)),
             state_von_mises=np.zeros((0, len(cells))), mode_v=np.zeros((0, len(points), 2)), modes_json="[]")
    return FieldData(path)


def test_a_rigid_motion_is_drawn_at_the_side_fraction(tmp_path):
    fd = _fields(tmp_path)
    v = np.tile([1.0, 0.0], (len(fd.points), 1))          # no edge changes: only the side bounds it
    assert fd.mode_amplitude(v) == MODE_SIDE * 40.0
    assert fd.element_size() == 10.0                      # the median edge: the 10 x 10 cells' sides


def test_a_node_moving_alone_is_drawn_at_a_fraction_of_its_edges(tmp_path):
    """One contact node slipping while its neighbours stay: drawn at 30 % of its shortest edge,
    never past them, on a coarse and on a fine mesh."""
    for nx, ny in ((8, 4), (64, 32)):
        fd = _fields(tmp_path, nx, ny)
        v = np.zeros((len(fd.points), 2))
        v[nx // 2] = [1.0, 0.0]                          # a node of the bottom edge
        h = 80.0 / nx
        assert np.isclose(fd.mode_amplitude(v), MODE_EDGE * h)      # its shortest edges: h long
        assert fd.mode_amplitude(v) < h                   # its neighbours are h away: never passed


def test_a_linear_field_is_bounded_by_its_gradient(tmp_path):
    """v = (y / H, 0) (a shear): every vertical edge changes by h / H of the largest displacement;
    the bound is MODE_EDGE H (edges of any length), then the side fraction wins."""
    fd = _fields(tmp_path)
    v = np.column_stack([fd.points[:, 1] / 40.0, np.zeros(len(fd.points))])
    # the diagonal edges change as much as the vertical ones (h / H), but are longer: the vertical bound
    assert np.isclose(fd.mode_amplitude(v), min(MODE_SIDE * 40.0, MODE_EDGE * 40.0))
