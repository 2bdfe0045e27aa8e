"""Contact islands and the broad phase kept between sub-steps (issue 15 item 3).

Island labels against scipy's connected components; the kept broad phase against a fresh one
(hypothesis: random boxes moved, turned and re-margined, same pairs in the same order, with
and without obstacles); impulses and Moreau-Jean island by island conserve momentum per island
and equal the sweep over all contacts; a whole contact run gives the same state kept or not.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse.csgraph import connected_components

from driftlog.columns import OMEGA, UB, VB, X, Y
from driftlog.contact import BallisticLogs, ContactModel, Obstacles, run_contacts
from driftlog.contact.broadphase import (
    PairCache,
    StaticGrid,
    brute_pairs,
    grid_pairs,
    log_boxes,
)
from driftlog.contact.impulses import resolve_impulses, resolve_islands
from driftlog.contact.islands import island_labels, islands, swept_islands
from driftlog.contact.moreau import moreau_solve
from driftlog.errors import ArgumentError


def _same_partition(a, b):
    """Two labellings describe the same components (label values may differ)."""
    pairs = np.unique(np.column_stack([a, b]), axis=0)
    return len(pairs) == len(np.unique(a)) == len(np.unique(b))


@pytest.mark.parametrize("n,k", [(1, 0), (10, 0), (50, 30), (2000, 1500), (2000, 4000)])
def test_islands_equal_scipy_components(rng, n, k):
    pairs = rng.integers(0, n, (k, 2))
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    labels = islands(pairs, n)
    g = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    count, ref = connected_components(g, directed=False)
    assert labels.max() + 1 == count
    assert _same_partition(labels, ref)
    # numbered by the smallest log of each island
    first = np.array([np.flatnonzero(labels == q)[0] for q in range(count)])
    assert np.all(np.diff(first) > 0)


def test_islands_ignore_obstacles_and_refuse_bad_pairs():
    # logs 0 and 2 both touch obstacle -1: not one island through the wall
    lab, count = island_labels(4, np.array([0, 2, 1]), np.array([-1, -1, 3]))
    assert count == 3 and lab[1] == lab[3] and len({lab[0], lab[2], lab[1]}) == 3
    with pytest.raises(ArgumentError, match="not below n = 3"):
        islands([[0, 5]], 3)
    with pytest.raises(ArgumentError, match=r"\(k, 2\)"):
        islands([0, 1, 2], 3)


def test_swept_islands_equal_brute_force(rng):
    """Swept centre boxes plus reach: the pairs of a brute-force box test, and their islands."""
    n = 600
    lo = rng.uniform(0, 40, (n, 2))
    swept = np.column_stack([lo, lo + rng.exponential(0.5, (n, 2))])
    reach = rng.uniform(0.3, 1.0, n)
    labels, pairs = swept_islands(swept, reach)
    x, y = swept[:, [0, 2]].mean(1), swept[:, [1, 3]].mean(1)
    ex = 0.5 * (swept[:, 2] - swept[:, 0]) + reach
    ey = 0.5 * (swept[:, 3] - swept[:, 1]) + reach
    ref = brute_pairs(x, y, ex, ey)
    assert set(map(tuple, pairs)) == set(map(tuple, ref)) and len(ref) > 100
    g = sp.coo_matrix((np.ones(len(ref)), (ref[:, 0], ref[:, 1])), shape=(n, n))
    count, comp = connected_components(g, directed=False)
    assert labels.max() + 1 == count and _same_partition(labels, comp)
    with pytest.raises(ArgumentError, match="xmax >= xmin"):
        swept_islands(swept[:, [2, 1, 0, 3]], reach)


def _logs(rng, n, side, spread_speed=1.0):
    S = np.zeros((n, 6))
    S[:, X:Y + 1] = rng.uniform(0, side, (n, 2))
    S[:, 2] = rng.uniform(0, np.pi, n)
    S[:, UB:VB + 1] = rng.normal(0, spread_speed, (n, 2))
    S[:, OMEGA] = rng.normal(0, 1, n)
    return S


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(2, 400), side=st.floats(2.0, 60.0),
       skin_factor=st.floats(0.0, 4.0), obstacles=st.booleans())
def test_kept_broad_phase_finds_every_fresh_pair(seed, n, side, skin_factor, obstacles):
    """Logs moved, turned and given new margins step after step: the kept broad phase returns
    exactly the fresh grid's pairs, in the same order (log-log and log-obstacle)."""
    rng = np.random.default_rng(seed)
    S = _logs(rng, n, side)
    length = rng.uniform(0.3, 2.0, n)
    radius = rng.uniform(0.02, 0.2, n)
    caps = np.column_stack([rng.uniform(0, side, (30, 2)), rng.uniform(0, side, (30, 2)),
                            rng.uniform(0, 0.3, 30)])
    caps[:10, 2:4] = caps[:10, 0:2]  # piers
    static = StaticGrid(caps, 2.0) if obstacles else None
    cache = PairCache(skin_factor)
    ex, ey = np.empty(n), np.empty(n)
    for _ in range(12):
        dt = rng.uniform(0.0, 0.3)
        margin = rng.uniform(0.0, 0.3, n) * rng.integers(0, 2)  # tol-like or motion-like
        skin = np.hypot(S[:, UB], S[:, VB]) * dt + np.abs(S[:, OMEGA]) * length * dt
        log_boxes(S, length, radius, margin, ex, ey)
        x, y = S[:, X].copy(), S[:, Y].copy()
        ll, lo = cache.pairs(x, y, ex, ey, skin, None, static)
        np.testing.assert_array_equal(ll, grid_pairs(x, y, ex, ey))
        if obstacles:
            np.testing.assert_array_equal(lo, static.query(x, y, ex, ey))
        S[:, X:Y + 1] += dt * S[:, UB:VB + 1] * rng.uniform(0, 1.5, (n, 1))
        S[:, 2] += dt * S[:, OMEGA]
    assert cache.builds + cache.reuses == 12


def _crowd(rng, g=14, spacing=1.1, L=1.0, r=0.08):
    xs = np.arange(g) * spacing
    gx, gy = np.meshgrid(xs, xs)
    n = g * g
    S = np.zeros((n, 6))
    S[:, X], S[:, Y] = gx.ravel(), gy.ravel()
    S[:, 2] = rng.uniform(0, np.pi, n)
    S[:, UB:VB + 1] = rng.normal(0, 1, (n, 2))
    S[:, OMEGA] = rng.normal(0, 1, n)
    return BallisticLogs(S, L, r, rng.uniform(500, 900, n))


def _per_island_momentum(S, mass, inertia, labels):
    q = labels.max() + 1
    px = np.bincount(labels, mass * S[:, UB], q)
    py = np.bincount(labels, mass * S[:, VB], q)
    lz = np.bincount(labels, mass * (S[:, X] * S[:, VB] - S[:, Y] * S[:, UB])
                     + inertia * S[:, OMEGA], q)
    return np.column_stack([px, py, lz])


def test_impulses_by_island_conserve_momentum_per_island(rng):
    """Touching pairs of a crowd (eps 0.4, logs of different densities): each island keeps
    its own linear and angular momentum, and the impulses equal the sweep over all contacts
    bit for bit."""
    b = _crowd(rng, g=20, spacing=1.0)
    m = ContactModel(restitution=0.4)
    C = m.detect(b, np.full(len(b.state), 0.05))
    C = C.select(C.gap <= 0.05)
    labels = islands(np.column_stack([C.body1, C.body2]), len(b.state))
    assert labels.max() + 1 < len(b.state) - 20  # islands of several logs
    inv_m, inv_i = 1 / b.mass, 1 / b.inertia
    p0 = _per_island_momentum(b.state, b.mass, b.inertia, labels)
    S1, S2 = b.state.copy(), b.state.copy()
    imp1, imp2 = np.zeros(len(C)), np.zeros(len(C))
    e1 = resolve_impulses(S1, inv_m, inv_i, C.body1, C.body2, C.res, 0.4, 1e-12, 10 ** 6, imp1)
    e2 = resolve_islands(S2, inv_m, inv_i, C.body1, C.body2, C.res, 0.4, 1e-12, 10 ** 6, imp2)
    assert e1 == e2 > 40
    np.testing.assert_array_equal(S1, S2)
    np.testing.assert_array_equal(imp1, imp2)
    p1 = _per_island_momentum(S2, b.mass, b.inertia, labels)
    scale = np.abs(p0).max()
    assert np.abs(p1 - p0).max() < 1e-13 * scale


def test_moreau_by_island_conserves_momentum_per_island(rng):
    """Moreau-Jean on a converging crowd: per-island momentum kept (no walls), and solving
    each island to the tolerance on its own stays within that tolerance of the lockstep
    solve."""
    b = _crowd(rng, g=20, spacing=1.0)
    b.state[:, UB:VB + 1] -= 0.5 * (b.state[:, X:Y + 1] - b.state[:, X:Y + 1].mean(0))
    m = ContactModel(method="moreau", restitution=0.3)
    dt = 0.02
    S0 = b.state.copy()
    C = m.detect_manifold(b, np.full(len(S0), 0.2), S=S0)
    labels = islands(np.column_stack([C.body1, C.body2]), len(S0))
    inv_m, inv_i = 1 / b.mass, 1 / b.inertia
    out = []
    for island_stop in (False, True):
        S = S0.copy()
        S[:, X:Y + 1] += dt * S0[:, UB:VB + 1]
        S[:, 2] += dt * S0[:, OMEGA]
        P = np.zeros(len(C))
        moreau_solve(S0, S, inv_m, inv_i, C.body1, C.body2, C.res, dt, 0.3, 5e-6, 5e-6, 1e-9,
                     500, P, 0.2, island_stop)
        assert (P > 0).sum() > 30
        p0 = _per_island_momentum(S0, b.mass, b.inertia, labels)
        p1 = _per_island_momentum(np.column_stack([S0[:, :3], S[:, 3:]]), b.mass, b.inertia,
                                  labels)
        assert np.abs(p1[:, :2] - p0[:, :2]).max() < 1e-12 * np.abs(p0).max()
        out.append(S)
    assert np.abs(out[0][:, UB:] - out[1][:, UB:]).max() < 1e-6


@pytest.mark.parametrize("method", ["event", "moreau"])
def test_kept_broad_phase_gives_the_same_run(rng, method):
    """A crowd in a box with a pier, 1.5 s of contacts: the same state bit for bit and the same
    hits with the broad phase kept between sub-steps as searched afresh at every call."""
    S0 = _crowd(rng, g=8, spacing=1.3).state
    S0[:, X:Y + 1] += 1.0
    runs = []
    for keep in (False, True):
        b = BallisticLogs(S0, 1.0, 0.08)
        obs = Obstacles()
        obs.add_polygon([[0, 0], [11.5, 0], [11.5, 11.5], [0, 11.5]], name="box")
        obs.add_circle([5.5, 5.5], 0.4, "pier")
        m = ContactModel(obs, method=method, restitution=0.7)
        m.keep_broad_phase = keep
        run_contacts(m, b, 1.5)
        runs.append((b.state.copy(), m.drain_hits(), m.backend.cache))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    for k in runs[0][1]:
        np.testing.assert_array_equal(runs[0][1][k], runs[1][1][k])
    assert len(runs[1][1]["time"]) > 30
    cache = runs[1][2]
    assert cache.reuses > 2 * cache.builds  # kept for several calls at a time


def _contacts_reference(S, length, radius, mem, na, nt, caps, ocaps, o0, o1, margin,
                        use_margin, gmax):
    """``island_kernel._contacts`` as it was before its sort and sweep: every pair tested,
    by first member, then the other members by position, then the first's capsules."""
    from driftlog.columns import NRES, THETA
    from driftlog.contact.geometry import capsule_gap, log_endpoints

    def box(a):
        i = mem[a]
        m = margin[a] if use_margin else gmax
        h = 0.5 * length[i]
        return (h * abs(np.cos(S[i, THETA])) + radius[i] + m,
                h * abs(np.sin(S[i, THETA])) + radius[i] + m)

    found = []
    out = np.empty(NRES)
    for a in range(na):
        i = mem[a]
        exi, eyi = box(a)
        ends = log_endpoints(S[i, X], S[i, Y], S[i, THETA], length[i])
        for b in range(a + 1, nt):
            j = mem[b]
            exj, eyj = box(b)
            if abs(S[i, X] - S[j, X]) > exi + exj or abs(S[i, Y] - S[j, Y]) > eyi + eyj:
                continue
            g = capsule_gap(*ends, radius[i], *log_endpoints(S[j, X], S[j, Y], S[j, THETA],
                                                             length[j]), radius[j], out)
            if use_margin or g <= gmax:
                found.append((a, b, *out))
        for k in range(o0, o1):
            qa, qb, qc, qd, qr = caps[ocaps[k]]
            if (S[i, X] - exi > max(qa, qc) + qr or S[i, X] + exi < min(qa, qc) - qr
                    or S[i, Y] - eyi > max(qb, qd) + qr or S[i, Y] + eyi < min(qb, qd) - qr):
                continue
            g = capsule_gap(*ends, radius[i], qa, qb, qc, qd, qr, out)
            if use_margin or g <= gmax:
                found.append((a, -(k - o0 + 1), *out))
    return found


@pytest.mark.parametrize("n,stopped,ncap,aspect", [(12, 0, 3, 1.0), (20, 4, 8, 1.0),
                                                   (300, 0, 0, 1.0), (300, 40, 25, 0.1),
                                                   (900, 60, 12, 8.0)])
@pytest.mark.parametrize("use_margin", [False, True])
def test_island_contacts_sweep_finds_every_pair_in_order(rng, n, stopped, ncap, aspect,
                                                         use_margin):
    """The event islands' contact search (sort and sweep above ``ALL_PAIRS`` bodies) finds
    the contacts of testing every pair, in the same order, with the same numbers: a jam of
    logs packed closer than their length (wider than long, or longer than wide: the sweep
    runs along either axis), some stopped (fixed), and pier capsules."""
    from driftlog.columns import NRES
    from driftlog.island_kernel import ALL_PAIRS, _contacts

    side = 2.2 * np.sqrt(n)  # 2-m logs about 2.2 m apart: many touch
    nrows = n + 7
    S = np.zeros((nrows, 6))
    # far from the origin: round-off in the pad
    S[:, X] = rng.uniform(0, side * np.sqrt(aspect), nrows) + 1e4
    S[:, Y] = rng.uniform(0, side / np.sqrt(aspect), nrows) - 3e3
    S[:, 2] = rng.uniform(-np.pi, np.pi, nrows)
    length = rng.uniform(1.5, 2.5, nrows)
    radius = rng.uniform(0.1, 0.2, nrows)
    mem = rng.permutation(nrows)[:n].astype(np.int64)
    na, nt = n - stopped, n
    cx = rng.uniform(0, side * np.sqrt(aspect), 40) + 1e4
    cy = rng.uniform(0, side / np.sqrt(aspect), 40) - 3e3
    caps = np.column_stack([cx, cy, cx + rng.uniform(-3, 3, 40), cy + rng.uniform(-3, 3, 40),
                            rng.uniform(0.2, 0.5, 40)])
    ocaps = np.concatenate([[39, 38], rng.permutation(38)[:ncap]]).astype(np.int64)
    o0, o1 = 2, 2 + ncap
    margin = rng.uniform(0.0, 0.4, n)
    cap = n * n + n * ncap + 1
    c1, c2, cres = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, NRES))
    nc = _contacts(S, length, radius, mem, na, nt, caps, ocaps, o0, o1, margin, use_margin, 0.05,
                   c1, c2, cres, np.empty((n, 6)))
    ref = _contacts_reference(S, length, radius, mem, na, nt, caps, ocaps, o0, o1, margin,
                              use_margin, 0.05)
    got = [(c1[k], c2[k], *cres[k]) for k in range(nc)]
    assert got == ref  # the same pairs, in the same order, bit for bit
    assert len(ref) > (n // 10 if n + ncap > ALL_PAIRS else 0)
    assert any(r[1] < 0 for r in ref) or ncap == 0 or not use_margin


def test_position_pass_pushes_no_pair_that_is_still_apart():
    """Split impulse (docs/model.md eq. (88)): an overlap deeper than the slop is removed 20 %
    a step by pseudo-velocities; a neighbour 2 cm away is not pushed, as the move closes only
    part of that gap.  (When every pair was held as if touching, the push went on to the
    neighbour and through a whole pile.)"""
    from driftlog.columns import GAP, NRES
    from driftlog.contact.geometry import capsule_gap, log_endpoints

    r, L, dt, slop = 0.08, 1.0, 0.1, 1e-5
    S0 = np.zeros((3, 6))
    S0[:, 0] = [0.0, 0.15, 0.15 + 2 * r + 0.02]  # overlap 1 cm, then a gap of 2 cm
    S0[:, 2] = np.pi / 2  # side by side, axes along y
    pairs = [(0, 1), (1, 2)]
    res = np.empty((2, NRES))
    for c, (a, b) in enumerate(pairs):
        capsule_gap(*log_endpoints(*S0[a, :3], L), r, *log_endpoints(*S0[b, :3], L), r, res[c])
    assert res[0, GAP] == pytest.approx(-0.01) and res[1, GAP] == pytest.approx(0.02)
    S = S0.copy()
    P = np.zeros(2)
    ones = np.ones(3)
    moreau_solve(S0, S, ones, ones, np.array([0, 1]), np.array([1, 2]), res, dt, 0.0, slop,
                 slop, 1e-12, 200, P, 0.2)
    assert np.all(P == 0.0)  # nothing approaches: no velocity impulse
    assert np.all(S[:, UB:] == 0.0)
    np.testing.assert_array_equal(S[2], S0[2])  # the neighbour apart is not pushed
    moved = S[:, 0] - S0[:, 0]
    # equal masses, levers zero: the two overlapping logs share 20 % of the overlap less the slop
    np.testing.assert_allclose(moved[:2], np.array([-0.5, 0.5]) * 0.2 * (0.01 - slop),
                               rtol=1e-9)
    np.testing.assert_array_equal(S[:, 1:3], S0[:, 1:3])


@pytest.mark.parametrize("solver", ["pgs", "nncg"])
def test_moreau_solve_on_a_reused_workspace_equals_fresh_solves(rng, solver):
    """The island kernel solves island after island on one workspace made once per call
    (``moreau_solve_into``, no allocation): solves of different sizes, one after another on
    a workspace poisoned with NaN and garbage first, give the fresh solves' numbers bit for bit
    (no work entry is read before it is written), restitution (its second solve) and deep
    overlaps (the position pass) included; by either solver."""
    from driftlog.contact.moreau import SOLVERS, moreau_solve_into, solve_workspace

    solver = SOLVERS.index(solver)
    fw, iw, bw, V, Vp = solve_workspace(4000, solver)
    fw[:] = np.nan
    iw[:] = -7
    bw[:] = True
    V[:] = np.nan
    Vp[:] = np.nan
    m = ContactModel(method="moreau", restitution=0.3)
    dt = 0.02
    for g, spacing, eps in ((20, 0.95, 0.3), (6, 0.9, 0.0), (12, 1.0, 0.8), (3, 0.9, 0.3)):
        b = _crowd(rng, g=g, spacing=spacing)
        S0 = b.state.copy()
        S0[:, UB:VB + 1] -= 0.5 * (S0[:, X:Y + 1] - S0[:, X:Y + 1].mean(0))
        C = m.detect_manifold(b, np.full(len(S0), 0.2), S=S0)
        assert C.gap.min() < -0.01  # deep overlaps: the position pass runs
        inv_m, inv_i = 1 / b.mass, 1 / b.inertia
        S = S0.copy()
        S[:, X:Y + 1] += dt * S0[:, UB:VB + 1]
        S[:, 2] += dt * S0[:, OMEGA]
        S1, S2 = S.copy(), S.copy()
        P1, P2 = np.zeros(len(C)), np.full(len(C) + 2, np.nan)
        r1 = moreau_solve(S0, S1, inv_m, inv_i, C.body1, C.body2, C.res, dt, eps, 5e-6, 5e-6,
                          1e-9, 300, P1, 0.2, False, solver)
        # the rows past n and k hold other data, as an island kernel's local rows do
        pad = np.vstack([S0, np.full((5, 6), np.nan)])
        S2 = np.vstack([S2, np.full((5, 6), np.nan)])
        r2 = moreau_solve_into(pad, S2, np.append(inv_m, np.ones(5)),
                               np.append(inv_i, np.ones(5)), len(S0),
                               np.append(C.body1, [0, 0]), np.append(C.body2, [1, 1]),
                               np.vstack([C.res, C.res[:2]]), len(C), dt, eps, 5e-6, 5e-6, 1e-9,
                               300, P2, 0.2, False, solver, fw, iw, bw, V, Vp)
        assert r1 == r2
        assert (P1 > 0).sum() >= 1
        assert S1.tobytes() == S2[:len(S0)].tobytes()
        assert P1.tobytes() == P2[:len(C)].tobytes()


@pytest.mark.parametrize("nt,stopped,ncap", [(2, 0, 0), (7, 2, 3), (16, 5, 8), (24, 0, 0),
                                             (12, 11, 12)])
def test_small_island_pairs_without_allocation_equal_island_pairs(rng, nt, stopped, ncap):
    """The Moreau-Jean island kernel's candidate pairs of an island of at most ``ALL_PAIRS``
    bodies (``_near_pairs``, into a work array) are ``_moving_pairs``' (``island_pairs`` less
    the pairs of two fixed bodies): the same pairs in the same order; and its least gap
    (``_near_gap``) is ``_min_gap``'s."""
    from driftlog.columns import NRES
    from driftlog.island_kernel import ALL_PAIRS
    from driftlog.moreau_kernel import _min_gap, _moving_pairs, _near_gap, _near_pairs

    assert nt + ncap <= ALL_PAIRS
    for _ in range(20):
        Sl = np.zeros((30, 6))
        side = 1.5 * np.sqrt(nt + ncap)
        Sl[:nt, X] = rng.uniform(0, side, nt) + 3e3
        Sl[:nt, Y] = rng.uniform(0, side, nt) - 1e3
        Sl[:nt, 2] = rng.uniform(-np.pi, np.pi, nt)
        ln = rng.uniform(1.0, 2.0, 30)
        rd = rng.uniform(0.05, 0.15, 30)
        margin = rng.uniform(0.0, 0.3, 30)
        cx = rng.uniform(0, side, 30) + 3e3
        cy = rng.uniform(0, side, 30) - 1e3
        caps = np.column_stack([cx, cy, cx + rng.uniform(-2, 2, 30),
                                cy + rng.uniform(-2, 2, 30), rng.uniform(0.1, 0.4, 30)])
        ocaps = rng.permutation(30)[:ncap].astype(np.int64)
        na = nt - stopped
        ref = _moving_pairs(Sl, ln, rd, na, nt, margin, caps, ocaps)
        out = np.full((ALL_PAIRS * ALL_PAIRS // 2, 2), -99, np.int64)
        m = _near_pairs(Sl, ln, rd, nt, na, margin, caps, ocaps, np.empty(ALL_PAIRS),
                        np.empty(ALL_PAIRS), out)
        np.testing.assert_array_equal(out[:m], ref)
        g = _near_gap(Sl, ln, rd, nt, caps, ocaps, 0.05, np.empty(ALL_PAIRS),
                      np.empty(ALL_PAIRS), np.empty(ALL_PAIRS), out, np.empty(NRES))
        assert g == _min_gap(Sl, ln, rd, nt, caps, ocaps, 0.05)
