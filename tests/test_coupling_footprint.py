"""A log's reaction shared among faces by the area of its plan over each (docs/model.md (72)).

The footprint is the rectangle length x diameter about the log's axis; each face takes the
share of its area inside it (``coupling_kernels.footprint_area``, a polygon cut to the four
sides), what lies outside the mesh or on a dry face goes to the face of the log's centre, and
the shares sum to the whole.  Spread over points along the axis instead (the code before),
the reaction fell on every other row of cells once the cells were finer than the points'
spacing, and the flow between the loaded rows ran faster: on the fixed array of validation
(a) the posts bore 934 N on 0.0625 m cells against about 500 N on coarser ones
(BENCHMARKS.md, "Two-way coupling: the reaction's footprint").
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from driftlog.coupling_kernels import footprint_area, spread_footprint, spread_reaction
from driftlog.mesher import channel_mesh


def _work(mesh):
    return np.empty((4, mesh.face_nodes.shape[1] + 4))


def _areas(mesh, cx, cy, theta, length, radius):
    loc, work = mesh.locator(), _work(mesh)
    return np.array([footprint_area(f, cx, cy, np.cos(theta), np.sin(theta), 0.5 * length,
                                    radius, loc, work) for f in range(mesh.n_faces)])


TRIANGLES = channel_mesh(10.0, 4.0, 0.37)
SQUARES = channel_mesh(10.0, 4.0, 0.5, structured=True)


@settings(max_examples=60, deadline=None)
@given(cx=st.floats(2.5, 7.5), cy=st.floats(1.6, 2.4), theta=st.floats(-np.pi, np.pi),
       length=st.floats(0.01, 2.0), radius=st.floats(0.005, 0.3))
def test_face_areas_under_a_log_tile_its_plan(cx, cy, theta, length, radius):
    """Over the faces of a mesh, the areas inside a log's plan sum to length x diameter."""
    for mesh in (TRIANGLES, SQUARES):
        a = _areas(mesh, cx, cy, theta, length, radius)
        assert np.all(a >= 0.0)
        np.testing.assert_allclose(a.sum(), 2.0 * radius * length, rtol=1e-11)
        assert a.sum() <= mesh.face_area.sum()


def test_face_area_under_an_axis_aligned_log_is_the_product_of_the_overlaps():
    """On squares, a log along y: each cell's area is its x overlap times its y overlap."""
    cx, cy, length, radius = 5.1, 2.03, 1.7, 0.2
    a = _areas(SQUARES, cx, cy, np.pi / 2, length, radius)
    loc = SQUARES.locator()
    nodes = SQUARES.face_nodes
    xs, ys = loc.node_x[nodes], loc.node_y[nodes]
    ox = np.clip(np.minimum(xs.max(1), cx + radius) - np.maximum(xs.min(1), cx - radius), 0, None)
    oy = np.clip(np.minimum(ys.max(1), cy + length / 2) - np.maximum(ys.min(1), cy - length / 2),
                 0, None)
    np.testing.assert_allclose(a, ox * oy, rtol=0, atol=1e-14)
    assert np.count_nonzero(a) == 8  # 0.4 m wide over x = 5 (two columns), y 1.18-2.88 (4 rows)


def _spread(mesh, logs, h):
    """Run spread_footprint on ``logs`` (x, y, theta, length, radius, gx, gy) rows."""
    loc = mesh.locator()
    L = np.asarray(logs, dtype=float)
    got = np.ascontiguousarray(L[:, 5:7])
    nf = mesh.n_faces
    sx, sy = np.zeros(nf), np.zeros(nf)
    touched = np.empty(nf + 8 * len(L), np.int64)
    mark = np.zeros(nf, np.int64)
    out = spread_footprint(got, L[:, 0].copy(), L[:, 1].copy(), np.cos(L[:, 2]), np.sin(L[:, 2]),
                           L[:, 3].copy(), L[:, 4].copy(), np.full(len(L), -1, np.int64), loc,
                           h, np.arange(nf), 1e-3, sx, sy, touched, 0, mark, 0,
                           np.empty(nf, np.int64), np.empty(nf), _work(mesh))
    nt, ux, uy, stamp = out
    assert len(set(touched[:nt].tolist())) == nt  # each face listed once
    assert set(np.flatnonzero((sx != 0) | (sy != 0)).tolist()) <= set(touched[:nt].tolist())
    return sx, sy, ux, uy, stamp


def test_spread_shares_by_area_dry_and_outside_parts_to_the_centre_face():
    mesh = TRIANGLES
    loc = mesh.locator()
    h = np.ones(mesh.n_faces)
    x, y, theta, length, radius = 4.0, 2.0, 0.7, 1.9, 0.15
    a = _areas(mesh, x, y, theta, length, radius)
    centre = int(loc_face(loc, x, y))
    # a dry face under the log, not its centre's
    dry = int(next(f for f in np.argsort(-a) if f != centre and a[f] > 0))
    h[dry] = 0.0
    g = np.array([120.0, -35.0])
    sx, sy, ux, uy, _ = _spread(mesh, [[x, y, theta, length, radius, *g]], h)
    whole = 2 * radius * length
    others = (a > 0) & (np.arange(mesh.n_faces) != centre) & (h > 0)
    np.testing.assert_allclose(sx[others], -g[0] * a[others] / whole, rtol=1e-14)
    np.testing.assert_allclose(sy[others], -g[1] * a[others] / whole, rtol=1e-14)
    assert sx[dry] == 0.0 and sy[dry] == 0.0
    # the centre's face: its own area and the dry face's
    np.testing.assert_allclose(sx[centre], -g[0] * (a[centre] + a[dry]) / whole, rtol=1e-12)
    assert abs(sx.sum() + g[0]) < 1e-13 * abs(g[0])
    assert abs(sy.sum() + g[1]) < 1e-13 * abs(g[1])
    assert ux == uy == 0.0
    # a log across the bank (y = 4): the part over the bank goes to its centre's face, a log
    # inside one face gives it all, a log off the mesh is undelivered
    f0 = int(np.argmax(mesh.face_area))
    fx, fy = mesh.face_x[f0], mesh.face_y[f0]
    sx, sy, ux, uy, _ = _spread(mesh, [[5.0, 3.9, 0.2, 1.0, 0.3, 10.0, 0.0],
                                       [fx, fy, 0.0, 0.001, 0.0005, 7.0, 1.0],
                                       [20.0, 2.0, 0.0, 1.0, 0.1, 3.0, 4.0]], np.ones(mesh.n_faces))
    assert (ux, uy) == (-3.0, -4.0)
    assert sx[f0] == -7.0 and sy[f0] == -1.0
    ab = _areas(mesh, 5.0, 3.9, 0.2, 1.0, 0.3)
    assert ab.sum() < 0.9 * 0.6  # part of the plan lies beyond the bank
    c = int(loc_face(loc, 5.0, 3.9))
    rest = sx.copy()
    rest[f0] += 7.0
    np.testing.assert_allclose(rest.sum(), -10.0, rtol=1e-14)
    np.testing.assert_allclose(rest[c], -10.0 * (1.0 - (ab.sum() - ab[c]) / 0.6), rtol=1e-12)


def loc_face(loc, x, y):
    from driftlog.locate import locate_one

    return locate_one(x, y, -1, loc)


def test_every_row_of_cells_under_a_log_takes_the_same_load_on_any_mesh():
    """No stripes: cells finer than the old points' spacing all take their share.

    A log of 1.8 m across the flow (along y), 0.3 m thick, its axis on the grid line x = 5:
    on 0.1, 0.05 and 0.025 m square cells each row of cells under it takes g x cell / L, in
    the same shares across the row (each column's overlap with the log's thickness).  Eight
    points along the axis (``spread_reaction``, the code before) loaded 8 cells of the 144
    under the log at 0.025 m, one row in 9, on one side of the axis.
    """
    x, y, length, radius = 5.0, 2.0, 1.8, 0.15
    g = np.array([300.0, 0.0])
    for cell in (0.1, 0.05, 0.025):
        mesh = channel_mesh(10.0, 4.0, cell, structured=True)
        sx, *_ = _spread(mesh, [[x, y, np.pi / 2, length, radius, *g]], np.ones(mesh.n_faces))
        assert np.all(np.abs(mesh.face_x[sx != 0] - x) < radius + cell)
        np.testing.assert_allclose(sx.sum(), -g[0], rtol=1e-14)
        row = np.round((mesh.face_y - y) / cell - 0.5).astype(int)
        inner = np.abs(mesh.face_y - y) < 0.5 * length - cell
        rows = np.unique(row[inner])
        by_row = np.array([sx[row == r] for r in rows])  # same columns in every row
        np.testing.assert_allclose(by_row.sum(1), -g[0] * cell / length, rtol=1e-12)
        # (slivers of round-off where a side of the log falls on a grid line: 1e-16 of g)
        np.testing.assert_allclose(by_row, np.broadcast_to(by_row[0], by_row.shape), rtol=1e-11,
                                   atol=1e-12 * g[0] * cell / length)
    loc = mesh.locator()
    nf = mesh.n_faces
    px, py = np.zeros(nf), np.zeros(nf)
    spread_reaction(np.array([g]), np.array([x]), np.array([y]), np.array([0.0]),
                    np.array([1.0]), np.array([length]), np.array([-1]), 8, loc,
                    np.ones(nf), np.arange(nf), 1e-3, px, py, np.empty(nf + 8, np.int64), 0)
    assert np.count_nonzero(px) == 8
    assert np.count_nonzero(sx) >= 144
