"""The contact model: the tracker calls ``substep`` each sub-step, ``drain_hits`` at records.

Two methods:

- ``event`` (the paper, docs/model.md sections 13.2-13.5): at the start of a sub-step, contacts
  within the tolerance get impulses (docs/model.md eq. (50), the paper's eq. 11-15); the step
  is then chosen so that no pair overlaps by more than the tolerance at its end, either by
  conservative advancement on the capsule distance (``toi.conservative_step``) or by the
  paper's dichotomy (take the step; while logs overlap at its end, halve it and redo; the next
  steps stay within the bracket where the overlap was seen, so that the bisection converges on
  the contact).  A sub-step may end before the one asked: at the next contact.  In a jam (many
  persistent contacts, eps < 1) the sub-steps collapse; the method counts events and sub-steps
  within one free sub-step and stops with ``ContactJamError`` (naming the logs, the time and
  the remedy) instead of looping.
- ``moreau`` (``moreau.moreau_solve``): the whole step is taken, and all contact impulses of
  the step are solved together by projected Gauss-Seidel; bounded cost, stable piles.

Masses are the logs' m_b and I_b (docs/model.md eq. (31), the paper's choice; see ``impulses``).

Hits (``drain_hits``) are contacts that start: one record per log and other body (a log id,
or -(obstacle index + 1)) at the instant the contact begins, with its impulse (Moreau-Jean:
the impulse of the step where it begins; an impact may spread over two steps).

"""

from __future__ import annotations

import numpy as np

from driftlog.columns import CX, CY, GAP, NRES, NX, NY, OMEGA, POSITION, UB, VB, VELOCITY
from driftlog.contact.impulses import resolve_islands, separate_resting
from driftlog.contact.islands import islands
from driftlog.contact.moreau import SOLVERS, moreau_solve
from driftlog.contact.native import NativeBackend, end_contacts
from driftlog.contact.obstacles import Obstacles
from driftlog.contact.toi import conservative_step, motion_margin, skin
from driftlog.errors import DriftlogError, ScenarioError
from driftlog.schema import Key, Section

__all__ = ["ContactModel", "ContactJamError", "Contacts"]


class ContactJamError(DriftlogError):
    """Event-driven contact stalled (a jam): too many events or sub-steps for no progress."""


class Contacts:
    """Contacts as arrays: bodies, obstacle index (-1 for log pairs), gap/normal/point."""

    def __init__(self, body1, body2, obstacle, res, key):
        self.body1, self.body2, self.obstacle, self.res = body1, body2, obstacle, res
        self.key = key  # one integer per (log, log or obstacle capsule) pair

    def __len__(self):
        return self.body1.size

    @property
    def gap(self):
        """Signed gaps (negative: overlap)."""
        return self.res[:, GAP]

    def select(self, mask):
        """The contacts where ``mask`` is true."""
        return Contacts(self.body1[mask], self.body2[mask], self.obstacle[mask], self.res[mask],
                        self.key[mask])


def rotates(bodies):
    """Whether contacts may turn these bodies: False for logs tracked with rotation off."""
    physics = getattr(bodies, "physics", None)
    return physics is None or bool(physics.rotation)


def _body_pairs(bodies, C):
    """One integer per (log, other body) by log id, stable when the floating set changes."""
    ids = bodies.ids
    other = np.where(C.body2 >= 0, ids[np.maximum(C.body2, 0)], (1 << 31) + C.obstacle)
    return ids[C.body1].astype(np.int64) * (1 << 32) + other


def _backend(name, obstacles):
    if name == "native":
        return NativeBackend(obstacles)
    if name == "fcl":
        from driftlog.contact.fcl_backend import FCLBackend

        return FCLBackend(obstacles)
    raise ScenarioError("contact.backend", name, "must be one of 'native', 'fcl'")


class ContactModel:
    """Contacts between logs, walls and obstacles.

    Parameters
    ----------
    obstacles : Obstacles, optional
    method : {"event", "moreau"}
    time_of_impact : {"conservative", "dichotomy"}
        How the event-driven method finds contact times.
    restitution : float
        eps in [0, 1].
    backend : {"native", "fcl"}
    tolerance : float
        Contact distance tolerance relative to the smallest log radius: pairs closer than this
        are in contact, and no accepted step overlaps by more.
    max_events : int
        Event-driven: impulses, or sub-steps, within one free sub-step above which the method
        stops (a jam).
    iterations : int
        Moreau: Gauss-Seidel sweeps at most per step.
    solver : {"pgs", "nncg"}
        Moreau: projected Gauss-Seidel (default), or the same sweeps with nonsmooth nonlinear
        conjugate gradient steps (Silcowitz et al. 2010; about a third of the sweeps on a pile
        of tens of logs, dearer on a raft of thousands).
    rest_speed : float
        Approach speeds below this do not bounce (resting contact; 0: the paper).  Without it a
        log pushed on a wall by the flow bounces ever less, ever more often (Zeno) and the
        event-driven step collapses.
    grounded : bool
        Resting and stranded logs are fixed capsules for the floating ones (the tracker gives
        them: ``set_grounded``); False (default): they take no part.  Opt-in: on the 1e4-log
        Malpasset flood a Moreau island collapsed to the minimum step with it (section 16).
    """

    # Moreau: the motion bounded per step near contacts is each near pair's relative motion
    # (eq. (81)); False: each near log's own motion in the ground's frame (the bound before
    # 2026-12-02, kept to compare: benchmarks/million_logs.py --motion absolute)
    relative_motion = True

    def __init__(self, obstacles=None, method="event", time_of_impact="conservative",
                 restitution=1.0, backend="native", tolerance=1e-4, max_events=10000,
                 iterations=200, rest_speed=0.01, grounded=False, solver="pgs"):
        if method not in ("event", "moreau"):
            raise ScenarioError("contact.method", method, "must be one of 'event', 'moreau'")
        if solver not in SOLVERS:
            raise ScenarioError("contact.solver", solver,
                                "must be one of " + ", ".join(f"'{v}'" for v in SOLVERS))
        if time_of_impact not in ("conservative", "dichotomy"):
            raise ScenarioError("contact.time_of_impact", time_of_impact,
                                "must be one of 'conservative', 'dichotomy'")
        if not 0.0 <= restitution <= 1.0:
            raise ScenarioError("contact.restitution", restitution, "must be in [0, 1]")
        self.obstacles = obstacles or Obstacles()
        # the capsules of the contact model: the obstacles', then the grounded logs' (resting
        # and stranded logs, fixed for the floating ones: ``set_grounded``); owner: the
        # obstacle index, or n_obstacles + the log's row (``ground_rows``) for a grounded log
        self.capsules, self.owner = self.obstacles.capsules, self.obstacles.owner
        self.grounded = bool(grounded)
        self.ground_rows = np.empty(0, np.int64)
        self._ground_ids = np.empty(0, np.int64)
        self.ground_version = 0
        # momentum passed to the bed through grounded logs by the contact impulses (x, y)
        self.ground_impulse = np.zeros(2)
        self.method, self.time_of_impact = method, time_of_impact
        self.restitution = float(restitution)
        self.backend = _backend(backend, self.obstacles)
        self.tolerance = float(tolerance)
        self.max_events = int(max_events)
        self.iterations = int(iterations)
        self.solver = SOLVERS.index(solver)  # moreau.PGS or moreau.NNCG
        self.rest_speed = float(rest_speed)
        self.check_overlap = True  # Moreau: measure the overlap after each step (stats)
        self.near = 0.05  # event: pairs closer than this share of the radius that separate
        # at their contact point do not bound the step (toi.conservative_step)
        self.motion_share = 0.25  # Moreau: motion per step near contacts, share of the radius
        # per-log clocks: contact islands in numba kernels (driftlog.island_kernel, event;
        # driftlog.moreau_kernel, Moreau-Jean); False runs the same islands through this model,
        # one after another (the reference the kernels are tested against)
        self.island_kernel = True
        self.stats = dict(substeps=0, advances=0, rejected=0, events=0, detections=0,
                          pgs_iterations=0, separations=0, pgs_max_iterations=0, pgs_capped=0,
                          max_contacts=0, min_gap=np.inf)
        self._hits = []
        # momentum passed to each fixed obstacle by the contact impulses (kg m/s, x and y)
        self.obstacle_impulse = np.zeros((len(self.obstacles.names), 2))
        self._cache = None
        self._window = None
        self._active = np.empty(0, np.int64)
        self._bracket = None
        self.keep_broad_phase = True  # broad phase kept between sub-steps (same results)
        self.island_stop = False  # Moreau: each island converges on its own (moreau_solve)
        self._skin = None
        self._last_step = None

    @property
    def n_owners(self):
        """Rows of a per-owner impulse array: the obstacles, then the grounded logs' rows."""
        n = len(self.obstacles.names)
        return n + (int(self.ground_rows[-1]) + 1 if self.ground_rows.size else 0)

    def set_grounded(self, rows, capsules, ids):
        """Resting and stranded logs as fixed capsules for the floating ones (section 13).

        ``rows``: increasing rows of the logs in the tracker's arrays; ``capsules`` (k, 5)
        their capsules; ``ids`` their ids (hit records name them).  Held by the bed, they take
        a contact's impulse as an obstacle does (``ground_impulse``).  Nothing changes when
        the set and its places are those already given.
        """
        rows = np.asarray(rows, np.int64)
        caps = np.asarray(capsules, float).reshape(-1, 5)
        ns = self.obstacles.capsules.shape[0]
        if (rows.size == self.ground_rows.size and np.array_equal(rows, self.ground_rows)
                and np.array_equal(caps, self.capsules[ns:])):
            return
        self.ground_rows = rows
        self._ground_ids = np.asarray(ids, np.int64)
        if rows.size:
            self.capsules = np.vstack([self.obstacles.capsules, caps])
            self.owner = np.concatenate([self.obstacles.owner,
                                         len(self.obstacles.names) + rows])
        else:
            self.capsules, self.owner = self.obstacles.capsules, self.obstacles.owner
        self.ground_version += 1
        self._cache = None
        self.backend.set_capsules(self.capsules, self.owner)

    def other_body(self, owner):
        """Hit records' ``other`` of contacts with capsule owners ``owner`` (arrays).

        -(obstacle index + 1) for an obstacle, the log id for a grounded log.
        """
        owner = np.asarray(owner, np.int64)
        n = len(self.obstacles.names)
        k = np.searchsorted(self.ground_rows, np.maximum(owner - n, 0))
        k = np.minimum(k, max(self.ground_rows.size - 1, 0))
        ids = self._ground_ids[k] if self.ground_rows.size else np.zeros_like(owner)
        return np.where(owner < n, -(owner + 1), ids)

    def pass_impulse(self, per_owner):
        """Add an impulse per owner (``n_owners``, 2) to the obstacles' and the bed's."""
        n = len(self.obstacles.names)
        self.obstacle_impulse += per_owner[:n]
        self.ground_impulse += per_owner[n:].sum(axis=0)

    @property
    def obstacle_names(self):
        """Names of the obstacles (hit records: other = -(index + 1))."""
        return list(self.obstacles.names)

    @classmethod
    def from_sections(cls, contact: dict, obstacles: list, mesh=None):
        """From a validated ``[contact]`` table (``CONTACT_SECTION``) and ``[[obstacles]]`` list.

        The mesh's wall boundaries become obstacles when ``contact["walls"]`` and a ``mesh``
        is given.
        """
        obs = Obstacles.from_tables(obstacles, mesh if contact["walls"] else None)
        return cls(obs, method=contact["method"], time_of_impact=contact["time_of_impact"],
                   restitution=contact["restitution"], backend=contact["backend"],
                   tolerance=contact["tolerance"], max_events=contact["max_events"],
                   iterations=contact["iterations"], rest_speed=contact["rest_speed"],
                   grounded=contact["grounded"], solver=contact["solver"])

    # ----------------------------------------------------------------- detection
    def _candidates(self, bodies, margin, S):
        skin = self._skin
        if self.keep_broad_phase and skin is not None and skin[0].size == S.shape[0]:
            return self.backend.candidates(S, bodies.length, bodies.radius, margin, skin,
                                           bodies.ids)
        return self.backend.candidates(S, bodies.length, bodies.radius, margin)

    def detect(self, bodies, margin, S=None):
        """Candidate contacts of ``bodies`` (tracker) within per-log ``margin``, measured.

        The broad phase is kept between calls (``broadphase.PairCache``, skin: the motion of
        the last sub-step asked) unless ``keep_broad_phase`` is False: the same contacts in
        the same order either way.
        """
        S = bodies.state if S is None else S
        ll, lo = self._candidates(bodies, margin, S)
        r_ll, r_lo = self.backend.gaps(S, bodies.length, bodies.radius, ll, lo)
        self.stats["detections"] += 1
        owner = self.owner
        n = S.shape[0]
        b1 = np.concatenate([ll[:, 0], lo[:, 0]])
        other = np.concatenate([ll[:, 1], n + lo[:, 1]])
        return Contacts(b1, np.concatenate([ll[:, 1], np.full(lo.shape[0], -1, np.int64)]),
                        np.concatenate([np.full(ll.shape[0], -1, np.int64),
                                        owner[lo[:, 1]] if lo.shape[0] else
                                        np.empty(0, np.int64)]),
                        np.vstack([r_ll, r_lo]), b1 * (n + owner.size) + other)

    def set_skin(self, bodies, dt, horizon=None):
        """How far each log may move before the next detection (the kept broad phase's skin).

        Its motion over ``horizon`` (default dt), at least the logs' mean motion over it (a
        log hit by another changes speed); the kept boxes also reach as far as the log moves
        in dt (the conservative-advancement query of the sub-step).  ``substep`` calls it.
        It changes the cost only, never the contacts found.
        """
        S, length, radius = bodies.state, bodies.length, bodies.radius
        h = dt if horizon is None else horizon
        self._skin = (skin(S, length, radius, h), skin(S, length, radius, dt))

    def islands(self, bodies, dt):
        """Contact islands of ``bodies`` over a step dt: an island label per log.

        Logs whose boxes, inflated by their motion over dt at their current velocities,
        overlap (directly or through other logs) share an island; contacts with walls and
        obstacles join nothing (``islands.islands``).
        """
        S = bodies.state
        margin = motion_margin(S, bodies.length, bodies.radius, dt, self._tol(bodies))
        ll, _ = self._candidates(bodies, margin, S)
        return islands(ll, S.shape[0])

    def detect_manifold(self, bodies, margin, S=None):
        """``detect`` plus the axis-end contacts of each pair (for the time-stepping solve)."""
        S = bodies.state if S is None else S
        C = self.detect(bodies, margin, S)
        if len(C) == 0:
            return C
        n = S.shape[0]
        is_ll = C.body2 >= 0
        ll = np.column_stack([C.body1[is_ll], C.body2[is_ll]])
        caps = C.key[~is_ll] % (n + self.owner.size) - n
        lo = np.column_stack([C.body1[~is_ll], caps])
        e_ll, e_lo = end_contacts(S, bodies.length, bodies.radius, self.capsules, ll, lo)
        rep = lambda a: np.repeat(a, 4)  # noqa: E731
        ends = Contacts(np.concatenate([rep(ll[:, 0]), rep(lo[:, 0])]),
                        np.concatenate([rep(ll[:, 1]), np.full(4 * len(lo), -1, np.int64)]),
                        np.concatenate([np.full(4 * len(ll), -1, np.int64),
                                        rep(C.obstacle[~is_ll])]),
                        np.vstack([e_ll.reshape(-1, NRES), e_lo.reshape(-1, NRES)]),
                        np.concatenate([rep(C.key[is_ll]), rep(C.key[~is_ll])]))
        # ends far apart (beyond the margin of the pair) cannot touch in this step; an end
        # across the other body's axis (crossed axes) would be pushed through it: only the
        # ends whose normal agrees with their pair's (docs/model.md eq. (86))
        m1 = margin[ends.body1] + np.where(ends.body2 >= 0, margin[np.maximum(ends.body2, 0)],
                                           0.0)
        pair = np.concatenate([np.repeat(C.res[is_ll, NX:NY + 1], 4, axis=0),
                               np.repeat(C.res[~is_ll, NX:NY + 1], 4, axis=0)])
        agree = ends.res[:, NX] * pair[:, 0] + ends.res[:, NY] * pair[:, 1] >= 0.0
        ends = ends.select((ends.gap <= m1) & agree)
        return Contacts(*(np.concatenate([a, b]) for a, b in
                          ((C.body1, ends.body1), (C.body2, ends.body2),
                           (C.obstacle, ends.obstacle))),
                        np.vstack([C.res, ends.res]), np.concatenate([C.key, ends.key]))

    def _tol(self, bodies):
        return self.tolerance * float(bodies.radius.min())

    def _touching(self, bodies, tol):
        """Contacts within tol at the current state (reusing the last step's end check)."""
        S = bodies.state
        key = (bodies.t, S.shape[0], self.ground_version)
        if self._cache is not None and self._cache[0] == key and np.array_equal(
                self._cache[1], S[:, POSITION]):
            C = self._cache[2]
        else:
            C = self.detect(bodies, np.full(S.shape[0], tol))
        return C.select(C.gap <= tol)

    def _remember(self, bodies, C):
        self._cache = ((bodies.t, bodies.state.shape[0], self.ground_version),
                       bodies.state[:, POSITION].copy(), C)

    # ----------------------------------------------------------------- hits
    def _record(self, bodies, C, impulse, t):
        hit = impulse > 0.0
        if not hit.any():
            return
        ids = bodies.ids
        b2 = C.body2[hit]
        other = np.where(b2 >= 0, ids[np.maximum(b2, 0)], self.other_body(C.obstacle[hit]))
        log = ids[C.body1[hit]]
        # one hit per log and body at an instant (a log on two edges of a polygon, or on
        # a pier at two points, is one hit): impulses summed, point impulse-weighted
        pair, inv = np.unique(np.column_stack([log, other]), axis=0, return_inverse=True)
        inv = inv.ravel()
        j = impulse[hit]
        jsum = np.bincount(inv, j, len(pair))
        self._hits.append(dict(time=np.full(len(pair), t), log_id=pair[:, 0], other=pair[:, 1],
                               impulse=jsum,
                               x=np.bincount(inv, j * C.res[hit, CX], len(pair)) / jsum,
                               y=np.bincount(inv, j * C.res[hit, CY], len(pair)) / jsum))

    def drain_hits(self):
        """Contacts since the last call: dict of arrays time, log_id, other, impulse, x, y."""
        keys = ("time", "log_id", "other", "impulse", "x", "y")
        if not self._hits:
            return {k: np.empty(0) for k in keys}
        out = {k: np.concatenate([h[k] for h in self._hits]) for k in keys}
        self._hits = []
        return out

    def _pass_to_obstacles(self, C, impulse):
        """Add to ``obstacle_impulse`` what the contacts ``C`` with impulses passed on.

        A contact impulse j n on a log (n from the other body to the log) is -j n on a fixed
        obstacle (on the bed, for a grounded log: ``ground_impulse``).
        """
        fixed = np.flatnonzero((C.body2 < 0) & (impulse != 0.0))
        if fixed.size == 0:
            return
        j = impulse[fixed]
        o = C.obstacle[fixed]
        n = self.n_owners
        per = np.column_stack([-np.bincount(o, j * C.res[fixed, NX], n),
                               -np.bincount(o, j * C.res[fixed, NY], n)])
        self.pass_impulse(per)

    # ----------------------------------------------------------------- stepping
    def substep(self, bodies, dt):
        """Advance ``bodies`` by at most dt with contacts; returns the step.

        ``bodies``: a ``driftlog.protocols.ContactBodies`` (the tracker, ``BallisticLogs``).
        """
        self.stats["substeps"] += 1
        if bodies.state.shape[0] == 0:
            bodies.advance(dt)
            return dt
        # the kept broad phase's skin: the motion over this sub-step, which is likely to end
        # within a few of the last one's lengths (event-driven steps end at the next contact)
        last = self._last_step
        self.set_skin(bodies, dt, None if last is None else min(dt, 8.0 * last))
        h = self._moreau(bodies, dt) if self.method == "moreau" else self._event(bodies, dt)
        self._last_step = h
        return h

    def _inverse_masses(self, bodies):
        """Inverse masses and inertias of the bodies.

        Logs that do not rotate (``physics.rotation = "off"``, theta and omega frozen,
        docs/model.md 9) have an infinite inertia: no contact turns them.
        """
        if rotates(bodies):
            return 1.0 / bodies.mass, 1.0 / bodies.inertia
        return 1.0 / bodies.mass, np.zeros_like(bodies.mass)

    def _jam(self, bodies, C, why):
        logs = np.concatenate([C.body1, C.body2[C.body2 >= 0]]) if len(C) else np.empty(0, int)
        ids, counts = np.unique(bodies.ids[logs], return_counts=True) if logs.size else ([], [])
        worst = [int(i) for i in np.asarray(ids)[np.argsort(counts)[::-1][:10]]]
        raise ContactJamError(
            f"event-driven contact stalls at t = {bodies.t:.6g} s: {why}; logs {worst} are in "
            f"persistent contact ({len(C)} contacts, restitution {self.restitution}): a jam, "
            "where impulses and contact times cannot make progress.  Use contact.method = "
            "\"moreau\" (time-stepping contact, stable in jams), or raise contact.max_events")

    def _count(self, bodies, dt, events, C):
        """Jam watch: events and sub-steps within one free sub-step of simulated time."""
        w = self._window
        if w is None or bodies.t - w[0] >= w[1]:
            w = self._window = [bodies.t, dt, 0, 0]
        w[2] += events
        w[3] += 1
        if w[2] > self.max_events or w[3] > self.max_events:
            self._jam(bodies, C, f"{w[2]} impulses and {w[3]} sub-steps within {w[1]:.3g} s "
                      f"of simulated time (contact.max_events = {self.max_events})")

    def _event(self, bodies, dt):
        st = self.stats
        tol = self._tol(bodies)
        S = bodies.state
        C = self._touching(bodies, tol)
        events = 0
        moved = False  # a resting pair set apart: positions changed
        if len(C):
            inv_m, inv_i = self._inverse_masses(bodies)
            imp = np.zeros(len(C))
            vscale = float(np.abs(S[:, UB:VB + 1]).max()) + 1e-3
            events = resolve_islands(S, inv_m, inv_i, C.body1, C.body2, C.res,
                                     self.restitution, 1e-10 * vscale, self.max_events, imp,
                                     self.rest_speed)
            if events < 0:
                self._jam(bodies, C, f"{self.max_events} impulses in one sub-step and contacts "
                          "still approach (contact.max_events)")
            st["events"] += events
            self._pass_to_obstacles(C, imp)
            st["max_contacts"] = max(st["max_contacts"], len(C))
            # a hit is a contact that starts (a log resting on a pier, bounced back by the
            # flow at every step, is one hit)
            pairs = _body_pairs(bodies, C)
            self._record(bodies, C, np.where(np.isin(pairs, self._active), 0.0, imp),
                         bodies.t)
            if self.rest_speed > 0.0 and separate_resting(S, inv_m, C.body1, C.body2, C.res,
                                                          self.rest_speed):
                st["separations"] += 1
                bodies.invalidate_flow()
                moved = True
        self._active = _body_pairs(bodies, C)
        # the tracker's first stage, computed by its max_step at this state, holds unless the
        # contacts changed the state (``Tracker.advance``'s have_d0: ``keeps_first_stage``)
        bound = getattr(bodies, "max_step", None)
        kept = getattr(bodies, "keeps_first_stage", False)
        have_d0 = kept and not moved and not events
        if (events or moved) and bound is not None:
            # the impulses changed velocities: the sub-step bound (44) of the new ones (a log
            # stopped dead at a pier relaxes to the flow faster than it moved with it; the
            # bound from before let it step on past the pier); its first stage is the step's
            dt = min(dt, bound())
            have_d0 = kept
        self._count(bodies, dt, events, C)
        h = dt
        if self.time_of_impact == "conservative":
            margin = motion_margin(S, bodies.length, bodies.radius, dt, tol)
            A = self.detect(bodies, margin)
            if len(A):
                h = conservative_step(S, bodies.length, bodies.radius, A.body1, A.body2, A.res,
                                      tol, dt, self.near * float(bodies.radius.min()))
        elif self._bracket is not None:
            # dichotomy: an overlap was seen by time _bracket; bisect up to it, do not jump it
            if events or bodies.t >= self._bracket:
                self._bracket = None
            else:
                h = min(h, self._bracket - bodies.t)
        min_step = bodies.min_step
        while True:
            if h < min_step:
                self._jam(bodies, C, f"the contact sub-step fell to {h:.3g} s (below "
                          f"min_step = {min_step:.3g} s)")
            saved = bodies.save()
            if have_d0:  # the first try only: a try overwrites the first stage
                bodies.advance(h, have_d0=True)
                have_d0 = False
            else:
                bodies.advance(h)
            st["advances"] += 1
            E = self.detect(bodies, np.full(bodies.state.shape[0], tol))
            gmin = float(E.gap.min()) if len(E) else np.inf
            if gmin >= -tol or self._overlaps_kept(C, E, tol):
                break
            bodies.restore(saved)
            if self.time_of_impact == "dichotomy":
                self._bracket = bodies.t + h
                h *= 0.5  # the paper
            else:
                # the bound held at constant velocities; a force closed the gap faster (a log
                # pushed on a wall): shorten the step in proportion to the closing measured
                h = self._shorter(C, E, tol, h)
            st["rejected"] += 1
        st["min_gap"] = min(st["min_gap"], gmin)
        self._remember(bodies, E)
        return h

    @staticmethod
    def _shorter(C, E, tol, h):
        """A step after which the deepest pair, closing as it did over h, ends above -tol."""
        k = int(np.argmin(E.gap))
        g_end = float(E.gap[k])
        same = np.flatnonzero(C.key == E.key[k])
        g0 = float(C.gap[same[0]]) if same.size else tol
        closing = g0 - g_end
        if closing <= 0.0:
            return 0.5 * h
        return min(0.5 * h, max(h / 16.0, 0.9 * h * max(g0 + tol, 0.0) / closing))

    @staticmethod
    def _overlaps_kept(C, E, tol):
        """True if every pair overlapping by more than tol at the end did so at the start.

        And deepened by less than tol: logs seeded overlapping are not a contact the step
        missed.
        """
        deep = E.gap < -tol
        order = np.argsort(C.key)
        k = np.searchsorted(C.key[order], E.key[deep])
        k = np.minimum(k, max(len(C) - 1, 0))
        if len(C) == 0:
            return False
        found = C.key[order][k] == E.key[deep]
        before = C.gap[order][k]
        return bool(np.all(found & (before < -tol) & (E.gap[deep] >= before - tol)))

    def _near_speed(self, S0, bodies, near):
        """The speed that bounds a Moreau step near contacts (eq. (81)).

        ``relative_motion``: the fastest change of a near pair's geometry, |U_1 - U_2| plus both
        bodies' turning rates times their reach (an obstacle's terms zero); otherwise the
        fastest near log's own speed (the bound before 2026-12-02).
        """
        if not self.relative_motion:
            idx = np.unique(np.concatenate([near.body1, near.body2[near.body2 >= 0]]))
            reach = 0.5 * bodies.length[idx] + bodies.radius[idx]
            return float((np.hypot(S0[idx, UB], S0[idx, VB])
                          + np.abs(S0[idx, OMEGA]) * reach).max())
        b1, b2 = near.body1, near.body2
        log = b2 >= 0
        o = np.where(log, b2, b1)
        reach = 0.5 * bodies.length + bodies.radius
        du = S0[b1, UB] - np.where(log, S0[o, UB], 0.0)
        dv = S0[b1, VB] - np.where(log, S0[o, VB], 0.0)
        turn2 = np.where(log, np.abs(S0[o, OMEGA]) * reach[o], 0.0)
        return float((np.hypot(du, dv) + np.abs(S0[b1, OMEGA]) * reach[b1] + turn2).max())

    def _moreau(self, bodies, dt):
        st = self.stats
        tol = self._tol(bodies)
        S0 = bodies.state.copy()
        t0 = bodies.t
        # near contacts, no pair moves against each other by more than a share of the smallest
        # radius per step (eq. (81)): the contact geometry is linearised at the step's start
        near = self.detect(bodies, motion_margin(S0, bodies.length, bodies.radius, dt, tol))
        if len(near):
            speed = self._near_speed(S0, bodies, near)
            if speed > 0.0:
                dt = min(dt, self.motion_share * float(bodies.radius.min()) / speed)
        bodies.advance(dt)
        st["advances"] += 1
        S = bodies.state
        # candidates over the motion of the step: start and free-end velocities
        fast = S0.copy()
        fast[:, VELOCITY] = np.maximum(np.abs(S0[:, VELOCITY]), np.abs(S[:, VELOCITY]))
        margin = motion_margin(fast, bodies.length, bodies.radius, dt, tol)
        C = self.detect_manifold(bodies, margin, S=S0)
        if len(C) == 0:
            self._active = np.empty(0, np.int64)
            return dt
        inv_m, inv_i = self._inverse_masses(bodies)
        P = np.zeros(len(C))
        vtol = 1e-9 * (float(np.abs(S[:, UB:VB + 1]).max()) + 1e-3)
        it, resid = moreau_solve(S0, S, inv_m, inv_i, C.body1, C.body2, C.res, dt,
                                 self.restitution, tol, tol, vtol, self.iterations, P, 0.2,
                                 self.island_stop, self.solver)
        st["pgs_iterations"] += it
        st["pgs_capped"] += int(resid > vtol)
        self._pass_to_obstacles(C, P)
        st["pgs_max_iterations"] = max(st["pgs_max_iterations"], it)
        st["max_contacts"] = max(st["max_contacts"], len(C))
        bodies.invalidate_flow()
        if self.check_overlap:
            E = self.detect(bodies, np.full(S.shape[0], tol))
            if len(E):
                st["min_gap"] = min(st["min_gap"], float(E.gap.min()))
        # a hit is a contact that starts pushing (not one that keeps pushing)
        on = P > 0.0
        key = _body_pairs(bodies, C)
        new = on & ~np.isin(key, self._active)
        # touching or pushing: a contact that flickers within the tolerance is one hit
        self._active = key[on | (C.gap <= tol)]
        self._record(bodies, C, np.where(new, P, 0.0), t0)
        return dt


# --------------------------------------------------------------------- the scenario section
CONTACT_SECTION = Section("contact", [
    Key("enabled", "bool", False, "contacts between logs and with walls and obstacles"),
    Key("method", "str", "event", "event-driven impulses (the paper) or time-stepping "
        "non-smooth contact (Moreau-Jean, for jams)", choices=("event", "moreau")),
    Key("time_of_impact", "str", "conservative", "contact time: the paper's dichotomy or "
        "conservative advancement on the capsule distance",
        choices=("dichotomy", "conservative")),
    Key("restitution", "float", 1.0, "coefficient of restitution eps", min=0.0, max=1.0),
    Key("backend", "str", "native", "distance queries: numba kernels or python-fcl",
        choices=("native", "fcl")),
    Key("walls", "bool", True, "the mesh's wall boundaries are obstacles"),
    Key("tolerance", "float", 1e-4, "contact distance tolerance, relative to the log radius",
        min=0.0, exclusive_min=True),
    Key("max_events", "int", 10000, "contact events per sub-step above which the event-driven "
        "method stops with a jam message", min=1),
    Key("rest_speed", "float", 0.01, "event-driven: approach speeds below this do not bounce "
        "(resting contact: a log held on a wall by the flow would otherwise bounce ever less, "
        "ever more often, and stall the method; 0 = the paper)", "m/s", min=0.0),
    Key("iterations", "int", 200, "moreau: projected Gauss-Seidel sweeps at most per step",
        min=1),
    Key("solver", "str", "pgs", "moreau: the contact impulses by projected Gauss-Seidel, or by "
        "the same sweeps with nonsmooth nonlinear conjugate gradient steps (about a third of "
        "the sweeps on a pile of tens of logs, dearer on a raft of thousands; docs/model.md "
        "(54b))", choices=SOLVERS),
    Key("grounded", "bool", False, "resting and stranded logs are fixed obstacles to the "
        "floating ones (held by the bed; docs/model.md 13, 16: not yet robust in dense "
        "floods); false: floating logs pass over them"),
], doc="contacts (docs/model.md section 13)")
