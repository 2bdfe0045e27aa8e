"""The shallow-water solver: state, options and the time step.

Cell-centred finite volumes on triangles and quadrilaterals (mixed): Godunov fluxes (HLLC or
HLL) with the hydrostatic reconstruction, explicit Euler with the CFL step at first order, or
MUSCL (limited least-squares gradients) with Heun's method at second order; semi-implicit
Manning friction.  The state is three flat arrays on faces (h, hu, hv); every per-cell and
per-edge loop is a numba kernel, and all work arrays are allocated once.

Inside, large meshes are renumbered for locality and the flux kernels run over the active set
of faces (wet faces and their neighbours) only (``driftlog.solver.layout``); both give the
same results bit for bit, and everything the user sees (``h``, ``hu``, ``hv``, extremes, flow
files, boundaries) is in the mesh's own numbering.
"""

from __future__ import annotations

import numpy as np

from driftlog._numba import workers_spin, written_zeros
from driftlog.errors import ScenarioError
from driftlog.flow import DRY_DEPTH_MAX
from driftlog.solver.boundaries import DEPTH, DISCHARGE, LEVEL, WALL, BoundarySet
from driftlog.solver.extremes import ARRIVAL_DEPTH, Extremes, volume_sum
from driftlog.solver.fluxes import (
    boundary_volumes,
    edge_fluxes_1,
    edge_fluxes_2,
    face_residuals,
    face_sides,
    gather_boundary_flux,
    largest_rate,
)
from driftlog.solver.friction import corrector_stage, euler_stage, predictor_stage
from driftlog.solver.layout import (
    BLOCK,
    ORDERINGS,
    RUN,
    active_blocks,
    active_set,
    all_runs,
    block_tables,
    edge_order,
    face_order,
    face_runs,
    mark_active,
    mark_blocks,
)
from driftlog.solver.reconstruction import ENERGY_BOUNDS, NSTATE, limited_gradients, lsq_geometry
from driftlog.solver.riemann import RIEMANN

__all__ = ["ShallowWaterSolver", "GRAVITY", "DEFAULT_CFL"]

GRAVITY = 9.81
DEFAULT_CFL = {1: 0.9, 2: 0.8}
# second order: velocities desingularised below this fraction of the bed's largest step from a
# face to a neighbour (Thacker's bowl: 0.01 -> 3.0 m/s at most in the film, 0.03 -> 1.6 m/s,
# the flow moving at 0.7 m/s; a flat bed: never)
THIN_FRACTION = 0.03

# faces from which the kernels run on numba's threads: below, waking the thread pool at each
# of the ~8 kernel calls of a step costs more than the work (and far more on a loaded machine)
PARALLEL_FACES = 20000
# and a parallel solver runs a whole step on the serial kernels while fewer faces than this are
# active (the flux passes run over the active set; a dam-break valley is mostly dry for most
# of the flood): numba's workers wait passively (driftlog/_numba.py) and waking them costs
# 50-100 us a kernel call on a virtual machine.  Where the user lets them spin
# (GOMP_SPINCOUNT), waking costs little and every step runs in parallel.  Serial and prange
# kernels give the same numbers (no reductions in them).
PARALLEL_ACTIVE = 0 if workers_spin() else 20000
# faces from which the mesh is renumbered for locality (reverse Cuthill-McKee): below, the
# state and the edge arrays fit in the caches and the mesher's numbering costs nothing
RENUMBER_FACES = 20000


def _per_face(value, n, key):
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = a.reshape(1)
    elif a.shape != (n,):
        raise ScenarioError(key, f"array of shape {a.shape}", f"must be a scalar or one value "
                            f"per face ({n})")
    if not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ScenarioError(key, value, "must be finite and >= 0")
    return a


class ShallowWaterSolver:
    """A 2D shallow-water model on a mesh.

    Parameters
    ----------
    mesh : driftlog.mesh.Mesh
        Triangles and/or quadrilaterals; boundary edges carry tags (``mesh.tag_names``).
    bed : array (n_faces,), optional
        Bed elevation on faces (m); default ``mesh.face_bed()`` (0 without node elevations).
    order : {1, 2}
        1: piecewise constant, explicit Euler; 2: MUSCL + Heun.
    riemann : {"hllc", "hll"}
    cfl : float, optional
        Fraction of the positivity-preserving time step (default 0.9 at order 1, 0.8 at 2).
    manning : float or array (n_faces,), optional
        Manning coefficient n (s m^-1/3).
    strickler : float or array, optional
        Strickler K = 1/n (m^1/3 s^-1); give manning or strickler, not both.
    dry_depth : float
        Depth (m) below which a face has no velocity.
    boundaries : dict tag -> Boundary | dict | str
        Conditions by boundary tag; tags not given are walls.
    arrival_depth : float
        Depth (m) that marks the arrival of the flood at a face (default 0.05 m).
    gravity : float
    parallel : bool, optional
        Run the kernels on numba's threads (default: from PARALLEL_FACES faces on, and then
        on one thread while fewer than PARALLEL_ACTIVE faces are active; True: always).
    thin_depth : float
        Depth (m) below which velocities are desingularised after every stage (Kurganov &
        Petrova 2007: u = sqrt(2) h (hu) / sqrt(h^4 + max(h^4, thin_depth^4)), hu reset to
        h u), so that a film at a wet/dry front carries no spurious speed (and does not set
        the time step).  Default 0: off.  It slows genuinely thin flows too: 1e-3 m suits
        metre-deep floods, not a 5 mm dam break (BENCHMARKS.md, solver section).
    thin_fraction : float, optional
        Second order: the same desingularisation below eps_i = thin_fraction * max_j |z_j - z_i|
        (j the face's neighbours), a depth that follows the bed's step across the face: a
        film thinner than a small part of that step is not resolved, and its velocity is
        not to be trusted.  Default 0.03 at order 2 (0 on a flat bed: nothing changes
        there); must be 0 at order 1.
    renumber : {"rcm", "hilbert", "none"}, optional
        Internal numbering of faces and edges (``driftlog.solver.layout``): reverse
        Cuthill-McKee, a Hilbert curve, or the mesh's own.  Default: "hilbert" from
        RENUMBER_FACES faces on (its blocks of consecutive faces are compact in space, so
        the active set's block pass on a partly dry mesh scans few of them; RCM's follow its
        levels across the whole mesh).  Results are the same bit for bit whichever is chosen.
    active_set : bool
        Run the flux kernels over the wet faces and their neighbours only (default True; the
        same results bit for bit, dry regions cost almost nothing).
    energy_bound : {"off", "g2", "rising", "velocity", "hr"}
        Second order on a bed given at the nodes: bound each edge's speed and total head by the
        largest of the face and its neighbours (docs/model.md eq. (85)), falling back to
        first-order depth and discharges where they are exceeded: "g2" at every edge, "rising"
        only at edges where the node bed makes the depth smaller than the limited depth,
        "velocity" an edge first taking the face's limited velocity reconstruction; "hr" no
        bound but the velocity of the limited depth and discharge where the node bed makes
        the edge shallower than the limited depth.  Default "off" (BENCHMARKS.md, Malpasset:
        the energy order 2 makes; the bound costs order on smooth flows).
    energy_widen : float
        The bounds of ``energy_bound`` widened by this fraction of the neighbourhood's speed
        and head ranges (default 0: none).
    """

    def __init__(self, mesh, bed=None, order=1, riemann="hllc", cfl=None, manning=None,
                 strickler=None, dry_depth=1e-6, boundaries=None, arrival_depth=ARRIVAL_DEPTH,
                 gravity=GRAVITY, parallel=None, thin_depth=0.0, renumber=None,
                 active_set=True, thin_fraction=None, energy_bound="off", energy_widen=0.0):
        if order not in (1, 2):
            raise ScenarioError("solver.order", order, "must be 1 or 2")
        if riemann not in RIEMANN:
            raise ScenarioError("solver.riemann", riemann, "must be one of 'hllc', 'hll'")
        cfl = DEFAULT_CFL[order] if cfl is None else float(cfl)
        if not 0 < cfl <= 1:
            raise ScenarioError("solver.cfl", cfl, "must be in (0, 1]: the fraction of the "
                                "positivity-preserving time step")
        thin_depth = float(thin_depth)
        if not (np.isfinite(thin_depth) and thin_depth >= 0):
            raise ScenarioError("solver.thin_depth", thin_depth, "must be a depth >= 0 m (0: "
                                "velocities from plain hu / h)")
        self._thin = float(thin_depth)
        thin_fraction = (THIN_FRACTION if order == 2 else 0.0) if thin_fraction is None \
            else float(thin_fraction)
        if not (np.isfinite(thin_fraction) and thin_fraction >= 0):
            raise ScenarioError("solver.thin_fraction", thin_fraction, "must be a fraction >= 0 "
                                "of the bed's step to a neighbour (0: off)")
        if order == 1 and thin_fraction > 0:
            raise ScenarioError("solver.thin_fraction", thin_fraction, "applies at order 2 "
                                "only (give 0 or leave it out at order 1)")
        self.thin_fraction = thin_fraction
        if energy_bound not in ENERGY_BOUNDS:
            raise ScenarioError("solver.energy_bound", energy_bound, "must be one of "
                                + ", ".join(repr(k) for k in ENERGY_BOUNDS))
        if order == 1 and energy_bound != "off":
            raise ScenarioError("solver.energy_bound", energy_bound, "applies at order 2 only")
        self.energy_bound = energy_bound
        energy_widen = float(energy_widen)
        if not (np.isfinite(energy_widen) and energy_widen >= 0):
            raise ScenarioError("solver.energy_widen", energy_widen, "must be a fraction >= 0")
        self.energy_widen = energy_widen
        if not 0 < dry_depth <= DRY_DEPTH_MAX:
            raise ScenarioError("solver.dry_depth", dry_depth,
                                f"must be > 0.0 and <= {DRY_DEPTH_MAX} m")
        self.mesh = mesh
        nf = mesh.n_faces
        bed_from_nodes = bed is None and mesh.node_z is not None
        if bed is None:
            bed = mesh.face_bed()
            bed = np.zeros(nf) if bed is None else bed
        self.bed = np.ascontiguousarray(bed, dtype=float)
        if self.bed.shape != (nf,) or not np.all(np.isfinite(self.bed)):
            raise ScenarioError("solver.bed", f"shape {self.bed.shape}",
                                f"must be {nf} finite values, one per face")
        if manning is not None and strickler is not None:
            raise ScenarioError("solver.strickler", strickler, "give manning or strickler, "
                                "not both")
        if strickler is not None:
            k = _per_face(strickler, nf, "solver.strickler")
            if np.any(k <= 0):
                raise ScenarioError("solver.strickler", strickler, "must be > 0")
            n = 1.0 / k
        else:
            n = _per_face(0.0 if manning is None else manning, nf, "solver.manning")
        self.manning = n
        self.order, self.riemann, self.cfl = int(order), riemann, cfl
        self.dry_depth, self.gravity, self.arrival_depth = float(dry_depth), float(gravity), \
            float(arrival_depth)
        par = nf >= PARALLEL_FACES if parallel is None else bool(parallel)
        self.parallel = par
        pick = (lambda k: k.parallel) if par else (lambda k: k.serial)
        kernels = (limited_gradients, edge_fluxes_1 if order == 1 else edge_fluxes_2,
                   face_residuals, euler_stage, predictor_stage, corrector_stage, mark_active)
        self._k_grad, self._k_edges, self._k_faces, self._k_euler, self._k_pred, \
            self._k_corr, self._k_mark = map(pick, kernels)
        # the kernels of a step whose active set is small (PARALLEL_ACTIVE), where the
        # parallel ones were chosen by the mesh's size (``parallel=True`` runs them always)
        self._k_serial = tuple(k.serial for k in kernels) if par and parallel is None else None
        self._small = False  # this step runs on them
        if renumber is None:
            renumber = "hilbert" if nf >= RENUMBER_FACES else "none"
        if renumber not in ORDERINGS:
            raise ScenarioError("solver.renumber", renumber, "must be one of "
                                + ", ".join(repr(o) for o in ORDERINGS))
        self.renumber = renumber
        self.active_set = bool(active_set)
        # internal numbering: face i of the kernels is the mesh's face _perm[i], edge j its
        # edge eperm[j] (each face keeps the order of its edges, each edge its orientation).
        # EVERY per-face or per-edge array a kernel reads must be in it: build it from the
        # internal arrays below (_z, _nbr, _fe, _ef, _area...) or map a mesh-numbered one with
        # faces_() / edges_(); face indices stored in an array map through new_face().
        # tests/test_solver_layout.py (renumbered == plain, bit for bit) catches a miss.
        ne = mesh.n_edges
        perm = face_order(mesh, renumber)
        self._identity = renumber == "none"
        inv = np.empty_like(perm)
        inv[perm] = np.arange(nf)
        self._perm, self._inv = perm, inv

        def new_face(old):
            return np.where(old >= 0, inv[np.maximum(old, 0)], -1)

        ef = new_face(mesh.edge_faces)
        eperm = np.arange(ne) if self._identity else edge_order(ef)
        einv = np.empty_like(eperm)
        einv[eperm] = np.arange(ne)

        def faces_(a):
            return np.ascontiguousarray(a[perm])

        def edges_(a):
            return np.ascontiguousarray(a[eperm])

        gn2 = self.gravity * n * n
        self._gn2 = faces_(gn2) if gn2.size == nf else np.ascontiguousarray(gn2)
        self._z = faces_(self.bed)
        self.boundaries = BoundarySet(mesh, boundaries, key="solver.boundaries")
        self.boundaries.renumber(inv, eperm, einv)
        # geometry, once
        self._ef = edges_(ef)
        self._nx = edges_(mesh.edge_normal[:, 0])
        self._ny = edges_(mesh.edge_normal[:, 1])
        self._len = edges_(mesh.edge_length)
        self._area = faces_(mesh.face_area)
        fe = mesh.face_edges[perm]
        self._fe = np.ascontiguousarray(np.where(fe >= 0, einv[np.maximum(fe, 0)], -1))
        self._fn = faces_(mesh.face_n)
        self._side = face_sides(self._fe, self._ef)
        self._nbr = np.ascontiguousarray(new_face(mesh.face_neighbours[perm]))
        if self.order == 2:
            self._lsq = tuple(faces_(g) for g in lsq_geometry(mesh))
            nbr = self._nbr
            # the gradients' neighbours: -1 an open boundary edge (no state beyond: its edge
            # value may go one range further), -2 a wall (its mirror state bounds the range)
            bs = self.boundaries
            ekind = np.full(ne, -1, dtype=np.int64)
            ekind[bs.edges] = bs.kind
            wall = (nbr < 0) & (self._fe >= 0) & (ekind[np.maximum(self._fe, 0)] == WALL)
            self._gnbr = np.ascontiguousarray(np.where(wall, -2, nbr))
            self._open_edge = np.ascontiguousarray((self._gnbr == -1).any(1))
            zj = self._z[np.where(nbr >= 0, nbr, np.arange(nf)[:, None])]
            self._thin_eps = self.thin_fraction * np.abs(zj - self._z[:, None]).max(1)
            # the reconstructed states of the two sides of each edge (written by the gradient
            # kernel once per stage, read by the edge kernel): row 2 e + s of _est, s = 0 for
            # the face edge e's normal points out of; _rows[f, k] the row of face f at its k-th
            self._est = written_zeros((2 * ne, NSTATE))
            # a bed given at the nodes (the default bed, mesh.face_bed()) is continuous and
            # piecewise linear: its value at an edge midpoint is the mean of the edge's two
            # nodes, the same from both sides (docs/model.md sect. 3.4)
            self._edge_bed = bool(bed_from_nodes)
            zedge = np.zeros(ne)
            if self._edge_bed:
                en = mesh.edge_nodes
                zedge = 0.5 * (mesh.node_z[en[:, 0]] + mesh.node_z[en[:, 1]])
            self._zedge = edges_(zedge)
            self._rows = np.ascontiguousarray(np.where(
                self._fe >= 0, 2 * self._fe + 1 - self._side.astype(np.int64), 0))
            # every face starts with a dry face's edge states (faces outside the active set
            # keep them)
            # what each face's reconstruction got (the gradient kernel's ``mark``)
            self._fallback = written_zeros(nf, dtype=np.int8)
            self._ebound = ENERGY_BOUNDS[energy_bound]
            limited_gradients.serial(np.arange(nf, dtype=np.int64), np.zeros(nf), np.zeros(nf),
                                     np.zeros(nf), self._z, self.dry_depth, self._fn, self._gnbr,
                                     *self._lsq, self._rows, self._est, self._open_edge,
                                     self._fe, bs.slot, bs.kind, bs.value, self._zedge,
                                     self._edge_bed, self._ebound, self.energy_widen, self.gravity,
                                     self._fallback)
            self._eoff = self._lsq[2]
        else:
            self._est = np.zeros((0, NSTATE))  # no edge states at first order
            self._rows = np.zeros((0, 1), dtype=np.int64)
            self._eoff = np.zeros((0, 1, 2))
        # work arrays that kernels store to conditionally: written memory, not np.zeros'
        # untouched pages (``_numba.written_zeros``)
        self._flux = [written_zeros(ne) for _ in range(7 if self.order == 2 else 6)]
        if self.order == 1:
            self._flux.append(self._flux[5])  # speed1: unused at first order
        self._res = [written_zeros(nf) for _ in range(4)]
        self._save = [written_zeros(nf) for _ in range(3)]
        self._bflux_sum = written_zeros(self.boundaries.edges.size)
        # active set: the faces that open boundaries can fill are always in it
        bs = self.boundaries
        self._always = written_zeros(nf, dtype=np.bool_)
        self._always[bs.face[np.isin(bs.kind, (LEVEL, DEPTH, DISCHARGE))]] = True
        self._mark = written_zeros(nf, dtype=np.uint8)
        self._all_faces = np.arange(nf, dtype=np.int64)
        self._all_edges = np.arange(ne, dtype=np.int64)
        self._faces_buf = written_zeros(nf, dtype=np.int64)
        self._edges_buf = written_zeros(ne, dtype=np.int64)
        # the active set's block pass (``mark_blocks``): blocks of faces next to the blocks
        # active at the last two passes; None where the edges are not sorted by face
        self._blocks = block_tables(self._ef, self._nbr, nf) if self.active_set else None
        if self._blocks is not None:
            nbk = self._blocks[2].size - 1
            self._blk = [np.ones(nbk, np.uint8), np.ones(nbk, np.uint8)]  # last, before
            self._blk_new = written_zeros(nbk, np.uint8)
            self._blk_cand = written_zeros(nbk, np.uint8)
            self._blk_active = nbk  # active blocks at the last pass
        self.active_faces = nf  # faces of the last flux pass
        # the faces the stage kernels and the extremes update, as runs of consecutive faces:
        # the blocks of the last passes' active sets (``_stage_runs``), every face after the
        # state was set from outside (``_stage_full``: the first stage then makes every dry
        # face's discharges zero, as it always did)
        self._stage_all = all_runs(nf)
        self._stage_buf = written_zeros((-(-nf // BLOCK), 2), dtype=np.int64)
        self._stage_full = True
        self.face_updates = 0   # faces of all flux passes so far (statistics)
        # state, in the internal numbering (h, hu, hv give the mesh's)
        self._h = written_zeros(nf)
        self._hu = written_zeros(nf)
        self._hv = written_zeros(nf)
        self.t = 0.0
        self.steps = 0
        self.rejected_steps = 0  # second order: steps redone at the corrector's bound
        n_tags = len(mesh.tag_names)
        self.inflow_volume = np.zeros(n_tags)   # m3 entered through each tag so far
        self.outflow_volume = np.zeros(n_tags)  # m3 left through each tag so far
        self._vol_work = np.zeros(2 * n_tags)  # a step's volumes per tag (boundary_volumes)
        self.initial_volume = 0.0
        self.extremes = Extremes(nf, parallel=self.parallel, order=self._order)

    # ----------------------------------------------------------------- state
    @property
    def _order(self):
        return None if self._identity else self._perm

    def _public(self, a):
        if self._identity:
            return a
        out = a[self._inv]
        out.flags.writeable = False  # a copy: writing into it would change nothing
        return out

    def _assign(self, a, value):
        value = np.broadcast_to(np.asarray(value, dtype=float), a.shape)
        a[:] = value if self._identity else value[self._perm]

    @property
    def h(self):
        """Depth on the faces (m), in the mesh's numbering.

        Read-only on a renumbered mesh (a copy): assign a whole array (``solver.h = ...``)
        or use ``set_state``.
        """
        return self._public(self._h)

    @h.setter
    def h(self, value):
        self._assign(self._h, value)
        self._forget_blocks()

    @property
    def hu(self):
        """Unit discharge along x on the faces (m2/s), in the mesh's numbering."""
        return self._public(self._hu)

    @hu.setter
    def hu(self, value):
        self._assign(self._hu, value)
        self._forget_blocks()

    @property
    def hv(self):
        """Unit discharge along y on the faces (m2/s), in the mesh's numbering."""
        return self._public(self._hv)

    @hv.setter
    def hv(self, value):
        self._assign(self._hv, value)
        self._forget_blocks()

    @property
    def level(self):
        """Free-surface level h + z (m)."""
        return self.h + self.bed

    def volume(self) -> float:
        """Water volume in the domain (m3)."""
        # in the mesh's numbering: the sum's order, hence its round-off, does not depend on
        # the internal one (nor on the machine's threads: a compensated serial sum)
        return float(volume_sum(self.h, self.mesh.face_area))

    def volume_error(self, volume=None) -> float:
        """Volume now (or ``volume``, m3, if given) minus (initial + inflow - outflow), m3.

        Zero to round-off.
        """
        v = self.volume() if volume is None else volume
        return (v - self.initial_volume - float(self.inflow_volume.sum())
                + float(self.outflow_volume.sum()))

    def set_state(self, h, hu=0.0, hv=0.0, t=0.0):
        """Set the state (depth and unit discharges on faces) and restart the balance."""
        nf = self.mesh.n_faces
        h = np.broadcast_to(np.asarray(h, dtype=float), (nf,))
        if not np.all(np.isfinite(h)) or np.any(h < 0):
            raise ScenarioError("solver.initial", "depth", "depths must be finite and >= 0")
        self.h = h
        self.hu = hu
        self.hv = hv
        dry = self._h <= self.dry_depth
        self._hu[dry] = 0.0
        self._hv[dry] = 0.0
        self.t = float(t)
        self.steps = 0
        self.inflow_volume[:] = 0.0
        self.outflow_volume[:] = 0.0
        self.initial_volume = self.volume()
        self.extremes = Extremes(nf, parallel=self.parallel, order=self._order)
        self.extremes.update(self._h, self._hu, self._hv, self._z, self.t, self.dry_depth,
                             self.arrival_depth)

    def set_level(self, level, polygon=None, velocity=(0.0, 0.0)):
        """Still water (or a uniform velocity) up to ``level``, optionally only in a polygon."""
        h = np.maximum(float(level) - self.bed, 0.0)
        if polygon is not None:
            h = np.where(self.mesh.faces_in_polygon(polygon), h, 0.0)
        self.set_state(h, h * velocity[0], h * velocity[1])

    # ----------------------------------------------------------------- time step
    def _forget_blocks(self):
        """The state was set from outside: the next active-set pass scans the whole mesh."""
        self._stage_full = True
        if getattr(self, "_blocks", None) is not None:
            self._blk[0][:] = 1
            self._blk[1][:] = 1
            self._blk_active = self._blk_new.size

    def _next_blocks(self):
        """Rotate the block flags: the pass's new ones (``_blk_new``) become the last."""
        last, before = self._blk
        self._blk = [self._blk_new, last]
        self._blk_new = before

    def _stage_runs(self, both=False):
        """The faces a stage updates: the last pass's active set's blocks (``face_runs``).

        ``both``: and those of the pass before it (Heun's corrector writes the faces of both
        its stages).  Outside them every face is empty with zero residuals and discharges (a
        face that leaves the set has its residuals zeroed, ``layout.mark_active``), so the
        stage would leave it as it is (the same numbers as a stage over every face).
        """
        if self._stage_full or self._blocks is None:
            return self._stage_all
        last, before = self._blk
        n = face_runs(last, before if both else last, BLOCK, self._h.shape[0], RUN,
                      self._stage_buf)
        return self._stage_buf[:n]

    def _rates(self, h, hu, hv, t):
        """Fluxes and residuals of state (h, hu, hv) at time t; returns the max rate.

        The state is in the internal numbering (``_h``, ``_hu``, ``_hv``).
        """
        m = self
        bs = m.boundaries
        bs.update(t, h, m._z, m.dry_depth)
        dh, dhu, dhv, rate = m._res
        ser = m._k_serial
        if ser is not None:  # the last pass's set decides the marking's kernel
            m._small = m.active_faces < PARALLEL_ACTIVE
        k_grad, k_edges, k_faces, _, _, _, k_mark = ser if m._small else (
            m._k_grad, m._k_edges, m._k_faces, None, None, None, m._k_mark)
        if m.active_set and m._blocks is not None and 2 * m._blk_active < m._blk_new.size:
            # a small set: only the blocks of faces next to the last two sets' blocks
            last, before = m._blk
            na, ne, m._blk_active = mark_blocks(
                h, m._always, m._fn, m._nbr, m._mark, dh, dhu, dhv, rate, m._z, m.dry_depth,
                m._eoff, m._rows, m._est, m._ef, BLOCK, *m._blocks, last, before, m._blk_cand,
                m._blk_new, m._faces_buf, m._edges_buf)
            m._next_blocks()
            faces, edges = ((m._all_faces, m._all_edges) if na == h.shape[0]
                            else (m._faces_buf[:na], m._edges_buf[:ne]))
        elif m.active_set:
            faces, edges = active_set(k_mark, h, m._always, m._fn, m._nbr, m._ef, m._mark,
                                      m._all_faces, m._all_edges, m._faces_buf, m._edges_buf,
                                      dh, dhu, dhv, rate, m._z, m.dry_depth, m._eoff, m._rows,
                                      m._est)
            if m._blocks is not None:  # this pass's active blocks, for the next
                m._blk_active = active_blocks(m._mark, BLOCK, m._blk_new)
                m._next_blocks()
        else:
            faces, edges = m._all_faces, m._all_edges
        m.active_faces = faces.shape[0]
        m.face_updates += faces.shape[0]
        if ser is not None and m._small != (faces.shape[0] < PARALLEL_ACTIVE):
            m._small = not m._small
            k_grad, k_edges, k_faces = ser[:3] if m._small else (m._k_grad, m._k_edges,
                                                                 m._k_faces)
        if m.order == 2:
            offset, minv, eoff = m._lsq
            k_grad(faces, h, hu, hv, m._z, m.dry_depth, m._fn, m._gnbr, offset, minv, eoff,
                   m._rows, m._est, m._open_edge, m._fe, bs.slot, bs.kind, bs.value, m._zedge,
                   m._edge_bed, m._ebound, m.energy_widen, m.gravity, m._fallback)
        fm, fx0, fy0, fx1, fy1, sp, sp1 = m._flux
        if m.order == 1:
            k_edges(edges, m._ef, m._nx, m._ny, m._len, h, hu, hv, m._z, RIEMANN[m.riemann],
                    m.gravity, m.dry_depth, bs.slot, bs.kind, bs.value, fm, fx0, fy0, fx1, fy1,
                    sp)
        else:
            k_edges(edges, m._ef, m._nx, m._ny, m._len, h, m._z, m._est, RIEMANN[m.riemann],
                    m.gravity, m.dry_depth, bs.slot, bs.kind, bs.value, fm, fx0, fy0, fx1, fy1,
                    sp, sp1)
        k_faces(faces, m._fe, m._fn, m._side, m._area, fm, fx0, fy0, fx1, fy1, sp, sp1, m.order,
                dh, dhu, dhv, rate)
        return largest_rate(rate, faces)

    def step(self, dt_max=np.inf) -> float:
        """Advance one time step, at most ``dt_max`` s; returns the step taken."""
        rmax = self._rates(self._h, self._hu, self._hv, self.t)
        dt = self.cfl / rmax if rmax > 0 else np.inf
        dt = min(dt, dt_max)
        if not np.isfinite(dt):
            raise RuntimeError("the solver cannot choose a time step: the domain is dry and "
                               "still with no inflow; give an end time")
        fm = self._flux[0]
        bedges = self.boundaries.edges
        dh, dhu, dhv, _ = self._res
        if self.order == 1:
            gather_boundary_flux(fm, bedges, 1.0, self._bflux_sum, False)
            k_euler = self._k_serial[3] if self._small else self._k_euler
            runs = self._stage_runs()
            k_euler(self._h, self._hu, self._hv, dh, dhu, dhv, dt, self._gn2, self.dry_depth,
                    self._thin, self._h, self._hu, self._hv, runs)
        else:
            # the predictor and corrector stages go to work arrays; the state (h, hu, hv)
            # stays U^n until the Heun average, (U'' + U^n) / 2 written onto it (a + b is
            # b + a exactly: the average of the saved state and U'' as before, without copies)
            h1, hu1, hv1 = self._save
            h, hu, hv = self._h, self._hu, self._hv
            eps = self._thin_eps
            while True:
                gather_boundary_flux(fm, bedges, 0.5, self._bflux_sum, False)
                # Euler stage and thin layer (68)-(69) in one pass
                k_pred = self._k_serial[4] if self._small else self._k_pred
                k_pred(h, hu, hv, dh, dhu, dhv, dt, self._gn2, self.dry_depth, self._thin, eps,
                       h1, hu1, hv1, self._stage_runs())
                rmax1 = self._rates(h1, hu1, hv1, self.t + dt)
                if dt * rmax1 <= 1.0:
                    break
                # the corrector's own positivity bound is tighter than the predictor's (the
                # predicted state's waves are faster): redo the step at that bound
                self.rejected_steps += 1
                dt = self.cfl / rmax1
                self._rates(h, hu, hv, self.t)
            gather_boundary_flux(fm, bedges, 0.5, self._bflux_sum, True)
            # Euler stage from U', Heun average with U^n and thin layer in one pass
            k_corr = self._k_serial[5] if self._small else self._k_corr
            runs = self._stage_runs(both=True)
            k_corr(h1, hu1, hv1, dh, dhu, dhv, dt, self._gn2, self.dry_depth, self._thin, eps,
                   h, hu, hv, runs)
        # m3 out (> 0) or in (< 0) per boundary edge, summed per tag
        boundary_volumes(self._bflux_sum, dt, self.boundaries.tag, self.outflow_volume,
                         self.inflow_volume, self._vol_work)
        self.t += dt
        self.steps += 1
        self.extremes.update(self._h, self._hu, self._hv, self._z, self.t, self.dry_depth,
                             self.arrival_depth, serial=self._small, runs=runs)
        self._stage_full = False
        return dt

    def run(self, t_end, output=None, output_interval=None, progress=False, resume=False,
            attrs=None):
        """Advance to ``t_end`` (s), writing the flow file ``output`` every ``output_interval``.

        ``resume=True`` continues from the last snapshot of ``output`` (state, volume
        balance and extremes).  Returns a ``driftlog.solver.run.SolveResult`` (steps, wall
        time, cell-updates/s, volume error).
        """
        from driftlog.solver.run import run_solver

        return run_solver(self, t_end, output=output, output_interval=output_interval,
                          progress=progress, resume=resume, attrs=attrs)

    def set_from_flow(self, path, time=None):
        """Start from a flow file's snapshot at ``time`` (default its last) on the same mesh."""
        from driftlog.errors import FlowFileError
        from driftlog.flowfile import open_flow

        flow = open_flow(path, dry_depth=self.dry_depth)
        if flow.mesh.n_faces != self.mesh.n_faces:
            raise FlowFileError(f"{path}: has {flow.mesh.n_faces} faces, the solver's mesh "
                                f"{self.mesh.n_faces}: initial state from another mesh")
        times = np.asarray(flow.times)
        i = times.size - 1 if time is None else int(np.argmin(np.abs(times - time)))
        if time is not None and abs(times[i] - time) > 1e-9 * max(1.0, abs(time)):
            raise FlowFileError(f"{path}: no snapshot at t = {time} s (it has "
                                f"{times[0]}..{times[-1]} s)")
        snap = flow.read_snapshot(i)
        self.set_state(snap[0], snap[1], snap[2], t=float(times[i]))

    def advance_to(self, t_end):
        """Step until time ``t_end`` exactly (the last step is shortened); returns steps."""
        n = 0
        while self.t < t_end:
            self.step(t_end - self.t)
            n += 1
        return n
