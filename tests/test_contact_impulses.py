"""Impulses (docs/model.md eq. (50)): head-on (section 15.E), oblique, walls, simultaneous
contacts, conservation."""

import numpy as np
import pytest

from driftlog.contact import BallisticLogs, ContactModel, Obstacles, run_contacts
from driftlog.contact.impulses import kinetic_energy, momenta, resolve_impulses

BACKENDS = ["native", "fcl"]
# FCL's distances come from GJK iterations: about 1e-6 m; the native kernel is exact
ATOL = {"native": 1e-12, "fcl": 1e-5}


def _pair(u1, u2, gap=0.8, L=2.0, r=0.1):
    d = L + 2 * r + gap
    S = np.zeros((2, 6))
    S[0, [0, 3]] = -d / 2, u1
    S[1, [0, 3]] = d / 2, u2
    return BallisticLogs(S, L, r)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("toi", ["conservative", "dichotomy"])
@pytest.mark.parametrize("eps", [0.0, 0.3, 1.0])
def test_head_on_along_the_axis(eps, toi, backend):
    """docs/model.md 15.E: ((1 - eps) U1 + (1 + eps) U2) / 2 and symmetric; energy scales eps^2."""
    u1, u2 = 1.0, -0.5
    b = _pair(u1, u2)
    m = ContactModel(restitution=eps, time_of_impact=toi, backend=backend)
    e0 = kinetic_energy(b.state, b.mass, b.inertia)
    run_contacts(m, b, 2.0, max_step=0.25)
    after1 = ((1 - eps) * u1 + (1 + eps) * u2) / 2
    after2 = ((1 - eps) * u2 + (1 + eps) * u1) / 2
    assert b.state[:, 3] == pytest.approx([after1, after2], abs=ATOL[backend])
    assert np.abs(b.state[:, [4, 5]]).max() < ATOL[backend]
    mr = b.mass[0] / 2  # reduced mass
    rel0, rel1 = 0.5 * mr * (u1 - u2) ** 2, 0.5 * mr * (after1 - after2) ** 2
    assert rel1 == pytest.approx(eps ** 2 * rel0, abs=100 * ATOL[backend])
    e1 = kinetic_energy(b.state, b.mass, b.inertia)
    assert e0 - e1 == pytest.approx(rel0 - rel1, rel=1e-12, abs=100 * ATOL[backend])
    hits = m.drain_hits()
    assert len(hits["time"]) == 1
    t_star = 0.8 / (u1 - u2)
    tol = m.tolerance * 0.1
    assert abs(hits["time"][0] - t_star) <= tol / (u1 - u2) * 1.01
    assert hits["impulse"][0] == pytest.approx(mr * (1 + eps) * (u1 - u2), rel=10 * ATOL[backend])


def _expected_pair(S, mass, inertia, c, n, eps):
    """docs/model.md eq. (50) written out: velocities after impact of bodies 0 and 1 (or wall)."""
    out = S.copy()
    r = [c - S[k, :2] for k in range(S.shape[0])]
    cross = lambda a, b: a[0] * b[1] - a[1] * b[0]  # noqa: E731
    vel = [S[k, 3:5] + S[k, 5] * np.array([-r[k][1], r[k][0]]) for k in range(S.shape[0])]
    vrel = vel[0] - (vel[1] if S.shape[0] > 1 else 0)
    den = 1 / mass[0] + cross(r[0], n) ** 2 / inertia[0]
    if S.shape[0] > 1:
        den += 1 / mass[1] + cross(r[1], n) ** 2 / inertia[1]
    j = -(1 + eps) * (vrel @ n) / den
    out[0, 3:5] += j * n / mass[0]
    out[0, 5] += cross(r[0], n) * j / inertia[0]
    if S.shape[0] > 1:
        out[1, 3:5] -= j * n / mass[1]
        out[1, 5] -= cross(r[1], n) * j / inertia[1]
    return out, j


@pytest.mark.parametrize("eps", [0.5, 1.0])
def test_oblique_end_on_side(eps):
    """A vertical log falls end-first on the side of a horizontal one, off its centre: the
    horizontal log spins up; the velocities are those of eq. 11-15 at the contact point."""
    L, r, a = 2.0, 0.1, 0.6
    S = np.zeros((2, 6))
    S[0] = [a, 0.3 + L / 2 + 2 * r, np.pi / 2, 0.2, -1.0, 0.0]  # falls onto log 2
    S[1] = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    b = BallisticLogs(S, L, r)
    m = ContactModel(restitution=eps)
    run_contacts(m, b, 0.3 / 1.0 + 1e-3, max_step=0.05)
    # replay: free motion to the contact time, then the formula
    h = m.drain_hits()
    t = h["time"][0]
    S1 = S.copy()
    S1[:, :3] += t * S[:, 3:]
    c = np.array([h["x"][0], h["y"][0]])
    assert c == pytest.approx([a + 0.2 * t, r], abs=1e-4)
    ref, j = _expected_pair(S1, b.mass, b.inertia, c, np.array([0.0, 1.0]), eps)
    assert b.state[:, 3:] == pytest.approx(ref[:, 3:], rel=1e-4, abs=1e-6)
    assert h["impulse"][0] == pytest.approx(j, rel=1e-4)
    assert b.state[1, 5] < 0  # pushed down right of its centre: clockwise


@pytest.mark.parametrize("backend", BACKENDS)
def test_wall_flat_and_tilted(backend):
    obs = Obstacles()
    obs.add_segments([[-10, 0], [10, 0]], name="bank")
    # flat: the normal velocity reverses (times eps), nothing else changes
    S = np.array([[0.0, 1.0, 0.0, 0.3, -1.0, 0.0]])
    b = BallisticLogs(S, 2.0, 0.1)
    m = ContactModel(obs, restitution=0.5, backend=backend)
    run_contacts(m, b, 1.5, max_step=0.1)
    assert b.state[0, 3:] == pytest.approx([0.3, 0.5, 0.0], abs=ATOL[backend])
    h = m.drain_hits()
    assert list(h["other"]) == [-1] and m.obstacle_names == ["bank"]
    # tilted, eps = 1: the lower end hits, the log spins, kinetic energy is kept
    th = 0.4
    S = np.array([[0.0, 1.0, th, 0.0, -1.0, 0.0]])
    b = BallisticLogs(S, 2.0, 0.1)
    m = ContactModel(obs, restitution=1.0, backend=backend)
    e0 = kinetic_energy(b.state, b.mass, b.inertia)
    run_contacts(m, b, 0.6, max_step=0.1)
    assert kinetic_energy(b.state, b.mass, b.inertia) == pytest.approx(e0, rel=1e-12)  # any n
    assert b.state[0, 5] < -0.1  # the lower (left) end is pushed up: clockwise spin
    h = m.drain_hits()
    t = h["time"][0]
    S1 = S.copy()
    S1[:, :3] += t * S[:, 3:]
    ref, _ = _expected_pair(S1, b.mass, b.inertia, np.array([h["x"][0], h["y"][0]]),
                            np.array([0.0, 1.0]), 1.0)
    assert b.state[0, 3:] == pytest.approx(ref[0, 3:], rel=1e-4, abs=1e-5)


def test_simultaneous_contacts_newton_cradle():
    """Three logs end to end, the first strikes the two touching ones (eps = 1): the velocity
    passes down the line to the last one (sequential impulses)."""
    L, r = 1.0, 0.05
    S = np.zeros((3, 6))
    S[:, 0] = [-(L + 2 * r) - 0.5, 0.0, L + 2 * r + 1e-7]
    S[0, 3] = 1.0
    b = BallisticLogs(S, L, r)
    m = ContactModel(restitution=1.0, rest_speed=0.0)
    run_contacts(m, b, 0.6, max_step=0.1)
    assert b.state[:, 3] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)


def test_resolve_impulses_random_pairs_conserve(rng):
    """Random contacts between random logs, eps = 1: energy and momenta to round-off."""
    n, k = 50, 400
    S = np.zeros((n, 6))
    S[:, :2] = rng.uniform(-5, 5, (n, 2))
    S[:, 3:] = rng.normal(0, 1, (n, 3))
    mass = rng.uniform(10, 100, n)
    inertia = mass * rng.uniform(0.05, 1.0, n)
    b1 = rng.integers(0, n, k)
    b2 = (b1 + rng.integers(1, n, k)) % n
    ang = rng.uniform(0, 2 * np.pi, k)
    res = np.column_stack([np.zeros(k), np.cos(ang), np.sin(ang),
                           0.5 * (S[b1, :2] + S[b2, :2]) + rng.normal(0, 0.3, (k, 2))])
    e0, p0 = kinetic_energy(S, mass, inertia), momenta(S, mass, inertia)
    imp = np.zeros(k)
    # arbitrary normals need not settle (elastic cycles): stop after 5000 impulses
    ev = resolve_impulses(S, 1 / mass, 1 / inertia, b1, b2, res, 1.0, 0.0, 5000, imp)
    assert ev == -1 and np.count_nonzero(imp) > 100
    assert kinetic_energy(S, mass, inertia) == pytest.approx(e0, rel=1e-12)
    assert np.allclose(momenta(S, mass, inertia), p0, rtol=0, atol=1e-10 * np.abs(p0).max())
