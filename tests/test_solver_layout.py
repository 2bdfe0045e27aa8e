"""The solver's internal layout: renumbering for locality and the active set change no result.

Renumbered (reverse Cuthill-McKee or a Hilbert curve) and with or without the active set, a
run gives the mesh's own numbering's results bit for bit (every face sums the same fluxes in
the same order), on a dam break over a dry bed with an inflow and a free outflow and on a
sloshing lake in a bowl that wets and dries; the flow file, the extremes and a resumed run
are in the mesh's numbering.  A mesh whose faces are given in another order gives the same
flood to round-off (the edges are then oriented otherwise).
"""

import importlib.util
from pathlib import Path

import netCDF4
import numpy as np
import pytest

from driftlog.errors import ScenarioError
from driftlog.mesh import Mesh
from driftlog.mesher import channel_mesh, polygon_mesh, rectangle
from driftlog.solver import ShallowWaterSolver
from driftlog.solver.layout import edge_order, hilbert_order, rcm_order


def _dam_break(mesh, order, **kw):
    """A dam break over a dry, bumpy bed, with an inflow and a free outflow."""
    bed = 0.05 * np.exp(-((mesh.face_x - 2.0) ** 2) / 0.05)
    s = ShallowWaterSolver(mesh, bed=bed, order=order, manning=0.015,
                           boundaries={"inflow": {"type": "discharge",
                                                  "series": [[0, 0.0], [1, 0.02]]},
                                       "outflow": "free"}, **kw)
    s.set_state(np.where(mesh.face_x < 1.0, 0.2, 0.0))
    return s


def _bowl(order, **kw):
    """A tilted lake sloshing in a paraboloid bowl: fronts that wet and dry all the time."""
    mesh = polygon_mesh(rectangle(-2.5, -2.5, 2.5, 2.5), 0.15)
    bed = 0.1 * (mesh.face_x ** 2 + mesh.face_y ** 2)
    s = ShallowWaterSolver(mesh, bed=bed, order=order, **kw)
    s.set_state(np.maximum(0.2 + 0.1 * mesh.face_x - bed, 0.0))
    return s


def _same(a, b):
    for x, y in ((a.h, b.h), (a.hu, b.hu), (a.hv, b.hv)):
        assert np.array_equal(x, y)
    for x, y in zip(a.extremes.arrays().values(), b.extremes.arrays().values(), strict=True):
        assert np.array_equal(x, y, equal_nan=True)
    assert a.steps == b.steps and a.t == b.t
    assert a.volume_error() == b.volume_error()
    assert np.array_equal(a.inflow_volume, b.inflow_volume)
    assert np.array_equal(a.outflow_volume, b.outflow_volume)


@pytest.mark.parametrize("order", [1, 2])
def test_renumbering_and_active_set_change_nothing_on_a_dry_bed_dam_break(order):
    mesh = channel_mesh(8.0, 0.5, 0.08)
    plain = _dam_break(mesh, order, renumber="none", active_set=False)
    plain.advance_to(1.0)
    # the front has not reached the end: part of the channel is dry
    assert (plain.h == 0.0).sum() > mesh.n_faces // 3
    assert abs(plain.volume_error()) < 1e-13 * plain.volume()
    for renumber, active, par in (("none", True, False), ("rcm", False, False),
                                  ("rcm", True, False), ("hilbert", True, False),
                                  ("rcm", True, True)):  # the prange kernels too
        s = _dam_break(mesh, order, renumber=renumber, active_set=active, parallel=par)
        s.advance_to(1.0)
        _same(s, plain)
        if active:  # the dry part of the channel was skipped
            assert s.face_updates < 0.9 * plain.face_updates


@pytest.mark.parametrize("order", [1, 2])
def test_active_set_changes_nothing_where_fronts_wet_and_dry(order):
    plain = _bowl(order, renumber="none", active_set=False)
    s = _bowl(order, renumber="rcm", active_set=True)
    dried = 0
    for _ in range(6 if order == 1 else 4):  # (order 2 then slows down: issue 14, item 2)
        was_wet = plain.h > 0
        plain.advance_to(plain.t + 0.5)
        s.advance_to(s.t + 0.5)
        dried += int((was_wet & (plain.h <= plain.dry_depth)).sum())
        _same(s, plain)
    assert dried > 0  # fronts retreated as well as advanced
    assert abs(s.volume_error()) < 1e-13 * s.volume()
    assert s.face_updates < 0.8 * plain.face_updates


@pytest.mark.parametrize("order", [1, 2])
def test_stages_and_extremes_skip_the_blocks_the_water_cannot_reach(order):
    """The Euler stage (Heun's two at second order) and the extremes run on the blocks of the
    last passes' active sets only: the same flood bit for bit as over every face, on the bowl
    whose fronts wet and dry, with a part of the blocks given to them.  At second order the
    predicted state is zero on every empty face after each step: the predictor does not write
    faces outside its blocks, so they must already hold what it would write there."""
    plain = _bowl(order, renumber="none", active_set=False)
    s = _bowl(order, renumber="hilbert", active_set=True)
    given, total = [0], [0]
    runs = s._stage_runs

    def counted(both=False):
        out = runs(both)
        given[0] += int((out[:, 1] - out[:, 0]).sum())
        total[0] += s.mesh.n_faces
        return out

    s._stage_runs = counted
    step = s.step

    def checked(dt_max=np.inf):
        dt = step(dt_max)
        if order == 2:
            empty = s._h == 0.0
            assert empty.any()
            for a in s._save:
                assert not a[empty].any()
        return dt

    s.step = checked
    for _ in range(4):
        plain.advance_to(plain.t + 0.5)
        s.advance_to(s.t + 0.5)
        _same(s, plain)
    assert given[0] < 0.8 * total[0]  # dry blocks skipped


def test_corrector_zeroes_the_prediction_of_a_face_it_empties():
    """A face dry at the start of a step that the predictor wets and the corrector empties
    again (its second stage clipped at zero) keeps no predicted state: the next predictor may
    not run there (outside the active set's blocks), and the next flux pass must read there
    what it would have written, zeros."""
    from driftlog.solver.friction import corrector_stage

    n = 3
    h = np.array([0.0, 0.5, 0.0])
    hu, hv = np.array([0.0, 0.3, 0.0]), np.zeros(n)
    h1, hu1, hv1 = np.array([0.01, 0.5, 0.0]), np.array([0.002, 0.3, 0.0]), np.full(n, 1e-4)
    dh = np.array([-1.0, 0.0, 0.0])  # face 0: 0.01 - 0.1 < 0, clipped
    dhu, dhv = np.zeros(n), np.zeros(n)
    corrector_stage.serial(h1, hu1, hv1, dh, dhu, dhv, 0.1, np.zeros(1), 1e-6, 0.0,
                           np.zeros(n), h, hu, hv, np.array([[0, n]]))
    assert h[0] == 0.0 and hu[0] == 0.0
    assert h1[0] == hu1[0] == hv1[0] == 0.0  # emptied: zeroed
    assert h1[2] == hu1[2] == hv1[2] == 0.0  # empty all along
    assert h1[1] == 0.5 and hu1[1] == 0.3 and hv1[1] == 1e-4  # wet: the prediction kept


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("renumber", ["hilbert", "rcm"])
def test_block_pass_finds_the_active_set_of_the_full_scan(order, renumber, monkeypatch):
    """``mark_blocks`` (blocks next to the last two passes' active blocks) on a long channel
    whose front wets it: the same flood bit for bit as the whole-mesh scan, with the block
    pass run while the water holds a small part of the channel."""
    import driftlog.solver.model as model

    mesh = channel_mesh(40.0, 0.5, 0.08)
    plain = _dam_break(mesh, order, renumber="none", active_set=False)
    plain.advance_to(1.5)
    calls, scanned = [0], [0]
    mark = model.mark_blocks

    def counted(*args):
        out = mark(*args)
        calls[0] += 1
        scanned[0] += out[2]  # the blocks it found active
        return out

    monkeypatch.setattr(model, "mark_blocks", counted)
    s = _dam_break(mesh, order, renumber=renumber)
    assert s._blocks is not None
    s.advance_to(1.5)
    _same(s, plain)
    passes = s.steps * order + s.rejected_steps * order
    assert calls[0] > 0.9 * passes  # the block pass, not the scan, after the first passes
    assert scanned[0] < 0.25 * calls[0] * s._blk_new.size  # a small part of the channel
    # the state set from outside: the next pass scans the whole mesh again
    s.h = s.h
    assert s._blk_active == s._blk_new.size


@pytest.mark.parametrize("order", [1, 2])
def test_parallel_solver_runs_small_active_sets_on_the_serial_kernels(order, monkeypatch):
    """A parallel solver runs a step on the serial kernels while fewer faces than
    PARALLEL_ACTIVE are active (waking numba's workers costs more than the work): it changes
    which kernels run, on both sides of the threshold as the front wets the channel, not one
    number."""
    import driftlog.solver.model as model

    mesh = channel_mesh(8.0, 0.5, 0.08)
    plain = _dam_break(mesh, order, renumber="none", active_set=False, parallel=False)
    plain.advance_to(1.0)
    monkeypatch.setattr(model, "PARALLEL_FACES", 0)  # parallel chosen by the mesh's size
    monkeypatch.setattr(model, "PARALLEL_ACTIVE", mesh.n_faces // 4)
    s = _dam_break(mesh, order, renumber="rcm")
    assert s.parallel
    serial_steps = []
    step = s.step

    def counted(dt_max=np.inf):
        dt = step(dt_max)
        serial_steps.append(s._small)
        return dt

    s.step = counted
    s.advance_to(1.0)
    _same(s, plain)
    # the set grew past the threshold: both kinds of step were taken
    assert 0 < sum(serial_steps) < len(serial_steps)
    assert serial_steps[0] and not serial_steps[-1]
    # parallel=True runs the prange kernels at every step
    forced = _dam_break(mesh, order, renumber="rcm", parallel=True)
    forced.advance_to(0.1)
    assert forced._k_serial is None and not forced._small


def test_small_active_sets_run_serially_only_under_passive_waiting():
    """The serial steps are for numba's workers waiting passively (driftlog's default), whose
    waking costs more than a small set's work; where the user lets them spin
    (GOMP_SPINCOUNT, OMP_WAIT_POLICY=ACTIVE) waking is cheap and every step runs in
    parallel."""
    from driftlog._numba import workers_spin

    assert not workers_spin({"OMP_WAIT_POLICY": "PASSIVE"})
    assert not workers_spin({"OMP_WAIT_POLICY": "PASSIVE", "GOMP_SPINCOUNT": "0"})
    assert workers_spin({"OMP_WAIT_POLICY": "PASSIVE", "GOMP_SPINCOUNT": "30000"})
    assert workers_spin({"GOMP_SPINCOUNT": "infinite"})
    assert workers_spin({"OMP_WAIT_POLICY": "active"})


def test_flow_file_and_resume_in_the_mesh_numbering(tmp_path):
    mesh = channel_mesh(4.0, 0.5, 0.08)
    plain = _dam_break(mesh, 2, renumber="none", active_set=False)
    plain.run(1.0, output=tmp_path / "plain.nc", output_interval=0.25)
    part = _dam_break(mesh, 2, renumber="rcm")
    part.run(0.5, output=tmp_path / "part.nc", output_interval=0.25)
    again = _dam_break(mesh, 2, renumber="rcm")
    again.run(1.0, output=tmp_path / "part.nc", output_interval=0.25, resume=True)
    _same(again, plain)
    with netCDF4.Dataset(tmp_path / "plain.nc") as d1, netCDF4.Dataset(tmp_path / "part.nc") as d2:
        for name in ("time", "water_depth", "velocity_x", "volume", "volume_error",
                     "max_water_level", "arrival_time", "restart_momentum_x"):
            if name in d1.variables:
                assert np.array_equal(d1[name][:], d2[name][:], equal_nan=True), name
        assert "water_depth" in d1.variables and "max_water_level" in d1.variables


def test_a_permuted_mesh_gives_the_same_flood():
    mesh = channel_mesh(8.0, 0.5, 0.08)
    p = np.random.default_rng(1).permutation(mesh.n_faces)
    shuffled = Mesh(mesh.node_x, mesh.node_y, mesh.face_nodes[p])
    shuffled.tag_boundary("inflow", lambda x, y: x < 1e-6)
    shuffled.tag_boundary("outflow", lambda x, y: x > 8.0 - 1e-6)
    assert np.array_equal(np.sort(shuffled.edge_length[shuffled.edges_with_tag("inflow")]),
                          np.sort(mesh.edge_length[mesh.edges_with_tag("inflow")]))
    a = _dam_break(mesh, 1, renumber="none")
    b = _dam_break(shuffled, 1, renumber="rcm")
    a.advance_to(1.0)
    b.advance_to(1.0)
    assert a.steps == b.steps
    np.testing.assert_allclose(b.h, a.h[p], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.hu, a.hu[p], rtol=0, atol=1e-12)
    assert b.volume() == pytest.approx(a.volume(), rel=1e-13)
    assert abs(b.volume_error()) < 1e-13 * b.volume()


def test_orderings_are_permutations_with_local_neighbours():
    mesh = polygon_mesh(rectangle(0, 0, 100, 100), 2.0)
    ef = mesh.edge_faces[mesh.edge_faces[:, 1] >= 0]
    for perm in (rcm_order(mesh.edge_faces, mesh.n_faces),
                 hilbert_order(mesh.face_x, mesh.face_y)):
        assert np.array_equal(np.sort(perm), np.arange(mesh.n_faces))
        inv = np.empty_like(perm)
        inv[perm] = np.arange(perm.size)
        gap = np.abs(inv[ef[:, 0]] - inv[ef[:, 1]])
        # neighbours close in memory: far closer than in the mesher's numbering
        assert np.median(gap) < 0.2 * np.median(np.abs(ef[:, 0] - ef[:, 1]))
    new = rcm_order(mesh.edge_faces, mesh.n_faces)
    inv = np.empty_like(new)
    inv[new] = np.arange(new.size)
    efn = np.where(mesh.edge_faces >= 0, inv[np.maximum(mesh.edge_faces, 0)], -1)
    lo = np.where(efn[:, 1] >= 0, efn.min(1), efn[:, 0])[edge_order(efn)]
    assert np.all(np.diff(lo) >= 0)  # edges sorted by their (smaller) face


def test_renumbered_state_is_read_only_and_a_bad_ordering_is_named():
    mesh = channel_mesh(2.0, 0.5, 0.1)
    s = _dam_break(mesh, 1, renumber="rcm")
    with pytest.raises(ValueError):
        s.h[0] = 1.0  # a copy in the mesh's numbering: writing into it would be lost
    s.h = np.full(mesh.n_faces, 0.1)
    assert np.all(s.h == 0.1)
    with pytest.raises(ScenarioError, match="solver.renumber"):
        ShallowWaterSolver(mesh, renumber="morton")


@pytest.fixture(scope="module")
def signed_kernels(tmp_path_factory):
    """The flux-pass kernels with their np.uint64 index casts removed (numba's wrapped signed
    indices: the code before the casts), built by benchmarks/kernel_ablation.py."""
    path = Path(__file__).resolve().parent.parent / "benchmarks" / "kernel_ablation.py"
    spec = importlib.util.spec_from_file_location("kernel_ablation", path)
    ab = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ab)
    folder = tmp_path_factory.mktemp("signed")
    return {m: ab.variant_module(m, "signed", folder)
            for m in ("fluxes", "reconstruction", "layout")}


@pytest.mark.parametrize("order", [1, 2])
def test_unsigned_index_casts_change_no_number(order, signed_kernels, monkeypatch):
    """The flux pass with its indices unsigned gives the flood of the same kernels with
    numba's wrapped signed indices, bit for bit: a cast of an index that can be negative (an
    edge's outside face at a boundary, a wall's -2) would read outside its array.  A long
    channel whose front wets it (the block pass runs), an inflow, a free outflow and walls."""
    import driftlog.solver.model as model

    mesh = channel_mesh(40.0, 0.5, 0.08)
    plain = _dam_break(mesh, order, parallel=False, renumber="hilbert")
    plain.advance_to(1.5)
    fl, rc, lay = (signed_kernels[m] for m in ("fluxes", "reconstruction", "layout"))
    calls = [0]

    def counted(*args):
        calls[0] += 1
        return lay.mark_blocks(*args)

    monkeypatch.setattr(model, "mark_blocks", counted)
    s = _dam_break(mesh, order, parallel=False, renumber="hilbert")
    s._k_grad = rc.limited_gradients.serial
    s._k_edges = (fl.edge_fluxes_1 if order == 1 else fl.edge_fluxes_2).serial
    s._k_faces = fl.face_residuals.serial
    s.advance_to(1.5)
    assert calls[0] > 0.9 * s.steps * order  # the signed block pass ran
    _same(s, plain)


@pytest.mark.parametrize("order", [1, 2])
def test_the_largest_rate_of_the_active_set_is_the_whole_meshs(order, monkeypatch):
    """Each stage's time-step bound is taken over the active set's faces only
    (``fluxes.largest_rate``): on the channel the front wets, with the block pass, it equals
    ``rate.max()`` over every face at every stage (the faces outside hold rate 0)."""
    import driftlog.solver.model as model

    mesh = channel_mesh(40.0, 0.5, 0.08)
    checked = [0, 0]  # stages, stages with an active set smaller than the mesh
    largest = model.largest_rate

    def compared(rate, faces):
        out = largest(rate, faces)
        assert out == float(rate.max())
        checked[0] += 1
        checked[1] += faces.shape[0] < rate.shape[0]
        return out

    monkeypatch.setattr(model, "largest_rate", compared)
    s = _dam_break(mesh, order)
    s.advance_to(1.5)
    assert checked[0] >= s.steps * order and checked[1] > 0.9 * checked[0]


def test_boundary_volumes_are_numpys_bincounts_bit_for_bit():
    """The step's volumes per boundary tag (``fluxes.boundary_volumes``) are the numbers of
    ``np.bincount(tag, np.maximum(+-flux dt, 0))`` added to the totals, signed zeros included;
    a NaN flux reaches the totals (the step is refused afterwards, not hidden)."""
    from driftlog.solver.fluxes import boundary_volumes

    rng = np.random.default_rng(4)
    flux = rng.normal(0.0, 1.0, 500) * rng.choice([1e-12, 1.0, 1e3], 500)
    flux[::37] = 0.0
    flux[5::41] = -0.0
    tag = rng.integers(0, 4, 500)
    out0, in0 = rng.uniform(0, 10, 4), rng.uniform(0, 10, 4)
    out1, in1 = out0.copy(), in0.copy()
    boundary_volumes(flux, 0.37, tag, out1, in1, np.empty(8))
    v = flux * 0.37
    ref_out = out0 + np.bincount(tag, weights=np.maximum(v, 0.0), minlength=4)
    ref_in = in0 + np.bincount(tag, weights=np.maximum(-v, 0.0), minlength=4)
    assert out1.tobytes() == ref_out.tobytes() and in1.tobytes() == ref_in.tobytes()
    flux[7] = np.nan
    boundary_volumes(flux, 0.37, tag, out1, in1, np.empty(8))
    assert np.isnan(out1[tag[7]]) and np.isnan(in1[tag[7]])
