"""The FCL backend against the native kernels, and what FCL's other queries get wrong."""

import meshio
import numpy as np
import pytest

fcl = pytest.importorskip("fcl")

from driftlog.contact import ContactModel, Obstacles  # noqa: E402
from driftlog.contact.fcl_backend import FCLBackend, log_object  # noqa: E402
from driftlog.contact.geometry import capsule_gap, log_endpoints  # noqa: E402
from driftlog.contact.native import NativeBackend  # noqa: E402
from driftlog.errors import ScenarioError  # noqa: E402


def _random_logs(rng, n):
    S = np.zeros((n, 6))
    S[:, :2] = rng.uniform(-1.5, 1.5, (n, 2))
    S[:, 2] = rng.uniform(-np.pi, np.pi, n)
    return S, rng.uniform(0.3, 2.0, n), rng.uniform(0.02, 0.2, n)


def test_random_pairs_distances_and_normals(rng):
    """10,000 random log pairs: FCL's distance() and the native kernel agree on distances
    and normals of separated pairs, and on the depth of overlapping pairs whose axes do not
    cross; FCL has no depth for crossing axes (it returns -(r1 + r2))."""
    n = 10000
    S, L, r = _random_logs(rng, 2 * n)
    nat = np.empty((n, 5))
    req = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
    d_fcl = np.empty(n)
    n_fcl = np.empty((n, 2))
    for k in range(n):
        i, j = 2 * k, 2 * k + 1
        capsule_gap(*log_endpoints(S[i, 0], S[i, 1], S[i, 2], L[i]), r[i],
                    *log_endpoints(S[j, 0], S[j, 1], S[j, 2], L[j]), r[j], nat[k])
        res = fcl.DistanceResult()
        d_fcl[k] = fcl.distance(log_object(S[i, 0], S[i, 1], S[i, 2], L[i], r[i]),
                                log_object(S[j, 0], S[j, 1], S[j, 2], L[j], r[j]), req, res)
        w = res.nearest_points[0] - res.nearest_points[1]
        n_fcl[k] = w[:2] / max(np.hypot(w[0], w[1]), 1e-300)
    apart = nat[:, 0] > 1e-3
    assert apart.sum() > 3000
    # FCL's GJK stops at its tolerance: 1e-6 m typically, 3e-4 m at worst
    err = np.abs(d_fcl[apart] - nat[apart, 0])
    assert np.median(err) < 1e-6 and np.percentile(err, 99) < 1e-5 and err.max() < 1e-3
    cosang = np.clip(np.sum(n_fcl[apart] * nat[apart, 1:3], axis=1), -1, 1)
    ang = np.degrees(np.arccos(cosang))  # error ~ point error / distance: worst when close
    assert np.median(ang) < 1e-3 and ang.max() < 2.0
    seg = np.array([capsule_gap(*log_endpoints(S[2 * k, 0], S[2 * k, 1], S[2 * k, 2], L[2 * k]),
                                0.0, *log_endpoints(S[2 * k + 1, 0], S[2 * k + 1, 1],
                                                    S[2 * k + 1, 2], L[2 * k + 1]), 0.0,
                                np.empty(5)) for k in range(n)])
    rsum = r[0::2] + r[1::2]
    overlap = (nat[:, 0] < -1e-3) & (seg > 1e-3)  # overlapping capsules, axes apart
    assert overlap.sum() > 100
    assert np.abs(d_fcl[overlap] - nat[overlap, 0]).max() < 1e-4
    cross = seg < -1e-3  # axes cross: the native depth is the least translation
    assert cross.sum() > 500
    assert np.allclose(d_fcl[cross], -rsum[cross], atol=1e-4)
    assert np.all(nat[cross, 0] < -rsum[cross])


def test_backends_agree_on_obstacles(rng):
    """Piers (cylinders), walls (quads) and a log against both backends' gaps."""
    obs = Obstacles()
    obs.add_circle([0.3, -0.2], 0.4, "pier")
    obs.add_polygon([[-1, 1], [1, 1.2], [0.5, 2]], "island")
    S, L, r = _random_logs(rng, 3000)
    margin = np.full(len(S), 0.5)
    nat, fb = NativeBackend(obs), FCLBackend(obs)
    ll, lo = nat.candidates(S, L, r, margin)
    a = nat.gaps(S, L, r, ll[:2000], lo)
    b = fb.gaps(S, L, r, ll[:2000], lo)
    for x, y in zip(a, b, strict=True):
        assert np.abs(x[:, 0] - y[:, 0]).max() < 1e-3  # GJK tolerance on tall shapes
        # normal error ~ distance error / distance
        apart = x[:, 0] > 1e-2
        assert np.abs(x[apart, 1:3] - y[apart, 1:3]).max() < 5e-2


def test_collide_and_continuous_collide_are_unreliable_for_capsules(rng):
    """Why the FCL backend uses distance() only (measured on python-fcl 0.7, BENCHMARKS.md)."""
    req = fcl.CollisionRequest(enable_contact=True, num_max_contacts=4)
    errors = []
    for _ in range(300):
        S, L, r = _random_logs(rng, 2)
        S[1, :2] = S[0, :2] + rng.uniform(-0.2, 0.2, 2)  # axes cross
        out = np.empty(5)
        gap = capsule_gap(*log_endpoints(*S[0, :3], L[0]), r[0], *log_endpoints(*S[1, :3], L[1]),
                          r[1], out)
        res = fcl.CollisionResult()
        if not fcl.collide(log_object(*S[0, :3], L[0], r[0]), log_object(*S[1, :3], L[1], r[1]),
                           req, res):
            continue
        errors.append(abs(res.contacts[0].penetration_depth - (-gap)) / -gap)
    errors = np.array(errors)
    # collide()'s depth is off by more than 10 % for a good share of crossing capsules
    assert errors.size > 200 and np.mean(errors > 0.1) > 0.2
    # continuousCollide: a log crossing another (contact at t = 0.4) is not reported
    a = log_object(0, 0, 0, 2.0, 0.1)
    b = log_object(0, 1.0, 0, 2.0, 0.1)
    ccd = fcl.ContinuousCollisionRequest()
    cres = fcl.ContinuousCollisionResult()
    fcl.continuousCollide(a, a.getTransform(), b, fcl.Transform(b.getRotation(), [0, -1.0, 0]),
                          ccd, cres)
    assert not cres.is_collide  # wrong: they pass through each other


def _box_mesh(path, x0, x1, y0, y1, z0, z1):
    v = np.array([[x, y, z] for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)], float)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    meshio.write(path, meshio.Mesh(v, [("quad", np.array(quads))]))
    return path


@pytest.mark.parametrize("backend", ["native", "fcl"])
def test_mesh_obstacle_cut_by_the_logs_plane(tmp_path, backend):
    """A 3D pier (box mesh) cut at z: the log stops on its face with either backend."""
    from driftlog.contact import BallisticLogs, run_contacts

    path = str(_box_mesh(tmp_path / "pier.vtk", 2.0, 3.0, -1.0, 1.0, -2.0, 3.0))
    obs = Obstacles()
    obs.add_mesh(path, z=0.5, name="pier")
    assert len(obs.capsules) >= 4
    b = BallisticLogs(np.array([[0.0, 0.2, np.pi / 2, 1.0, 0.0, 0.0]]), 1.0, 0.1)
    m = ContactModel(obs, restitution=0.0, backend=backend)
    run_contacts(m, b, 3.0, max_step=0.2)
    h = m.drain_hits()
    assert len(h["time"]) == 1 and h["other"][0] == -1
    assert h["time"][0] == pytest.approx(1.9, abs=1e-3)  # face at x = 2, log radius 0.1
    # the face is cut as two segments (two triangles): two contact points, the log may turn
    assert b.state[0, 0] < 1.9 and b.state[0, 3] <= 1e-9
    assert m.stats["min_gap"] >= -m.tolerance * 0.1
    with pytest.raises(ScenarioError, match="does not cut"):
        Obstacles().add_mesh(path, z=5.0)
