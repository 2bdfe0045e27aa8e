import os

# pytest -n 2 runs two worker processes on a 2-core machine: one numba thread each, or four
# threads contend for two cores (set before numba is imported by the tests)
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False, help="run slow tests")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow") or os.environ.get("DRIFTLOG_SLOW") == "1":
        return
    skip = pytest.mark.skip(reason="slow: use --runslow or DRIFTLOG_SLOW=1")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


MALPASSET = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "malpasset")


def malpasset_dir():
    """The Malpasset data: ../shared/data/malpasset beside the checkout, or a copy in the repo."""
    for d in (os.environ.get("DRIFTLOG_MALPASSET"), MALPASSET,
              os.path.join(os.path.dirname(__file__), "..", "cases", "malpasset", "data")):
        if d and os.path.isfile(os.path.join(d, "malpasset_mesh.nc")):
            return os.path.abspath(d)
    return None


@pytest.fixture(scope="session")
def malpasset_mesh():
    d = malpasset_dir()
    if d is None:
        pytest.skip("Malpasset data not found")
    from driftlog.mesh import read_mesh

    return read_mesh(os.path.join(d, "malpasset_mesh.nc"))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def mixed_mesh():
    """A mesh of triangles and quadrilaterals: a 6 x 4 grid with the right half split."""
    from driftlog.mesh import Mesh

    g = Mesh.regular_grid(6, 4, 1.0)
    faces = []
    for f in g.face_nodes:
        cx = g.node_x[f].mean()
        if cx > 3:
            faces.append([f[0], f[1], f[2], -1])
            faces.append([f[0], f[2], f[3], -1])
        else:
            faces.append(list(f))
    # jitter interior nodes so that the mesh is not a grid
    x, y = g.node_x.copy(), g.node_y.copy()
    inner = (x > 0) & (x < 6) & (y > 0) & (y < 4)
    r = np.random.default_rng(1)
    x[inner] += r.uniform(-0.2, 0.2, inner.sum())
    y[inner] += r.uniform(-0.2, 0.2, inner.sum())
    return Mesh(x, y, np.array(faces))


def breaking_after(flow, t_break):
    """A copy of ``flow`` whose sampling raises KeyboardInterrupt past ``t_break`` (a Ctrl-C in
    the middle of a run, for the resume tests)."""

    class Breaks(type(flow)):
        def sample_into(self, x, y, t, face, out, flag):
            if t > t_break:
                raise KeyboardInterrupt
            super().sample_into(x, y, t, face, out, flag)

    broken = Breaks.__new__(Breaks)
    broken.__dict__.update(flow.__dict__)
    return broken


def draining_channel(mesh, times, location="face"):
    """Sheared, meandering flow to the east (out through the mesh's east side) over a bank
    (12 < x < 20, y > 6) that dries from 0.6 m at 0.05 m/s: the scene of the fused-step and
    per-log-clock tests.  ``location="node"``: the same flow given at the nodes (as TELEMAC
    or SCHISM write it)."""
    import numpy as np

    from driftlog.flow import MeshFlowField

    if location == "node":
        xc, yc = mesh.node_x, mesh.node_y
    else:
        xc, yc = mesh.face_x, mesh.face_y
    h, hu, hv = [], [], []
    for t in times:
        depth = np.where((xc > 12) & (xc < 20) & (yc > 6), max(0.6 - 0.05 * t, 0.0), 0.6)
        u = 0.8 + 0.3 * np.sin(yc / 2.0) + 0.01 * t
        v = 0.25 * np.cos(xc / 3.0)
        h.append(depth)
        hu.append(depth * u)
        hv.append(depth * v)
    return MeshFlowField.from_arrays(mesh, np.zeros(xc.size), times, np.array(h),
                                     np.array(hu), np.array(hv), location=location)
