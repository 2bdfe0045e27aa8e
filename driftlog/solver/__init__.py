"""driftlog's 2D shallow-water solver: the flow source the debris tracker runs on.

    from driftlog.mesher import channel_mesh
    from driftlog.solver import ShallowWaterSolver
    mesh = channel_mesh(10.0, 1.0, 0.05)
    solver = ShallowWaterSolver(mesh, order=1, manning=0.012,
                                boundaries={"inflow": {"type": "discharge", "value": 0.018},
                                            "outflow": {"type": "froude", "value": 0.18}})
    solver.set_level(0.05)
    result = solver.run(60.0, output="flow.nc", output_interval=1.0, progress=True)

Modules: ``riemann`` (HLL, HLLC), ``reconstruction`` (MUSCL gradients and limiter),
``boundaries`` (conditions by tag), ``friction`` (semi-implicit Manning, time stages),
``fluxes`` (edge and face kernels), ``extremes`` (maximum level, depth, speed, arrival),
``model`` (the solver and its time step), ``run`` (output, resume), ``config`` (the
``[solver]`` scenario section, the mesh and solver it builds; ``driftlog.solving``, at the
top, turns a whole scenario into a stored flow).
"""

from driftlog.solver.boundaries import Boundary
from driftlog.solver.config import build_solver
from driftlog.solver.model import ShallowWaterSolver
from driftlog.solver.run import SolveResult

__all__ = ["ShallowWaterSolver", "Boundary", "SolveResult", "build_solver"]
