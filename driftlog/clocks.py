"""Per-log clocks (``[integrator] clock = "per_log"``, docs/model.md section 11.1).

Algorithm 1 of the reference paper (docs/model.md section 11) advances all floating logs
together with the smallest sub-step any of them needs (``clock = "global"``).  With
``clock = "per_log"`` the logs meet only at the synchronisation times (hydrodynamic snapshots,
output times, releases, the end); between two of them each log takes its own sub-steps, from
its own bounds (eq. (70)), in one kernel over all logs (``driftlog.clock_kernel``).  Each
log's sub-steps are exactly the ones the global clock would give it alone: one log has the
same trajectory, bit for bit, under both clocks.

With contacts, the logs whose swept boxes may touch each other or an obstacle form contact
islands (connected components of the overlap graph); each island runs the global clock's
contact steps among its own logs, so its next contact ends only its own step
(``contact_advance``).
"""

from __future__ import annotations

import numpy as np

from driftlog.clock_kernel import (
    CLOCKS,
    DIVERGED,
    EULER,
    RK4,
    TOO_SMALL,
    per_log_mesh_advance,
)
from driftlog.contact.islands import island_labels
from driftlog.logs import FLOATING

__all__ = ["CLOCKS", "per_log_interval", "free_advance", "contact_advance", "touching"]


# --------------------------------------------------------------------- the tracker's side
def per_log_interval(tr, stop, bar=None):
    """Advance the tracker ``tr``'s floating logs to ``stop`` on their own clocks.

    Without contacts every log takes its own sub-steps (``free_advance``); with contacts the
    logs whose swept boxes may touch each other or an obstacle share the global clock's
    contact steps (``contact_advance``).  Then, at ``stop``: waterlogging over the interval,
    releases, statuses (as the global clock does after each sub-step).
    """
    t0 = tr.t
    if tr.contact is None:
        free_advance(tr, stop)
    else:
        contact_advance(tr, stop)
    tr.t = stop
    tr._soak(stop - t0)
    tr.stats["substeps"] += 1
    tr._release()
    tr._update_status()
    if bar is not None:
        bar.update(stop - t0)


def free_advance(tr, stop):
    """Every floating log of ``tr`` to ``stop`` with its own sub-steps (one kernel).

    Returns each log's swept box (n, 4: xmin, ymin, xmax, ymax of its centre over its
    sub-step ends).  A log whose status changes on the way stops there; the tracker then
    classifies it from the flow sampled where it stopped (``F``, as the global clock would).
    """
    from driftlog.columns import P_HSTAR
    from driftlog.stepping import IntegrationError, StepTooSmallError

    so, kern, n = tr.step_options, tr._kernel, tr.act.size
    if not tr._d0_valid:
        tr._rhs(tr.state, tr.t, tr.D0, tr.lin0)
    vals_c, T0c, gap_c, t_split = kern.node_pair(tr.t)
    if stop >= t_split:
        vals_n, T0n, gap_n, _ = kern.node_pair(stop)
    else:
        vals_n, T0n, gap_n = vals_c, T0c, gap_c
    friction = tr.physics.motion != "floating"
    thr = (tr.P[:, P_HSTAR].copy() if friction
           else np.ascontiguousarray(tr.logs.float_depth[tr.act]))
    t_log, dt_min, dt_max = np.empty(n), np.empty(n), np.empty(n)
    nsteps, code = np.empty(n, np.int64), np.empty(n, np.int8)
    box = np.empty((n, 4))
    tracer = tr.physics.level == "tracer"
    explicit = not tr.integrator.stiff_stable and not tracer
    method = RK4 if tr.integrator.name == "rk4" else EULER
    per_log_mesh_advance(
        tr.state, tr.D0, tr.lin0, tr.face, tr.F, tr.flag, tr.P, tr.opt, tr.t, stop,
        tr.time_tol, method, np.ascontiguousarray(tr.length), so.length_fraction,
        so.angle_step, so.drag_fraction, explicit, so.max_step if so.max_step else np.inf,
        so.min_step, tracer, bool(tr.physics.rotation), thr, friction, vals_c, T0c, gap_c,
        vals_n, T0n, gap_n, t_split, kern.dry_depth, kern.recovered, kern.locator, t_log,
        nsteps, dt_min, dt_max, box, code)
    tr._F_valid = tr._d0_valid = True
    k = int(nsteps.sum())
    st = tr.stats
    st["log_substeps"] = st.get("log_substeps", 0) + k
    st["rhs_evaluations"] += k * (4 if method == RK4 else 1)
    if k:
        st["min_dt"] = min(st["min_dt"], float(dt_min[nsteps > 0].min()))
        st["max_dt"] = max(st["max_dt"], float(dt_max.max()))
    bad = np.flatnonzero(code == TOO_SMALL)
    if bad.size:
        i = bad[0]
        raise StepTooSmallError(
            f"sub-step below integrator.min_step = {so.min_step} s for log {int(tr.ids[i])} "
            f"at t = {t_log[i]} s; a log spins or moves too fast for its length (check the "
            "flow at the logs) or lower integrator.min_step")
    bad = np.flatnonzero(code == DIVERGED)
    if bad.size:
        raise IntegrationError(
            f"the {tr.integrator.name} integration diverged at t = {t_log[bad[0]]:.6g} s "
            f"(logs {tr.ids[bad[:5]].tolist()}): the step is too long for the drag "
            "relaxation time; use integrator.method = 'exponential' or set "
            "integrator.drag_fraction > 0")
    return box


def _boxes(box, half):
    """Centres and half extents of swept boxes (xmin, ymin, xmax, ymax) grown by ``half``."""
    cx = 0.5 * (box[:, 0] + box[:, 2])
    cy = 0.5 * (box[:, 1] + box[:, 3])
    return cx, cy, 0.5 * (box[:, 2] - box[:, 0]) + half, 0.5 * (box[:, 3] - box[:, 1]) + half


def _obstacle_grid(tr, cell):
    """The contact model's obstacles binned for the swept boxes (kept while the cell fits)."""
    from driftlog.contact.broadphase import StaticGrid

    g = getattr(tr, "_clock_grid", None)
    if g is None or cell > 2.0 * g[0] or cell < 0.25 * g[0]:
        g = tr._clock_grid = (cell, StaticGrid(tr.contact.obstacles.capsules, cell))
    return g[1]


def touching(tr, box, half):
    """Logs whose swept boxes overlap another's or an obstacle's, and the log pairs."""
    from driftlog.contact.broadphase import grid_pairs

    cx, cy, ex, ey = _boxes(box, half)
    pairs = grid_pairs(cx, cy, ex, ey)
    hit = np.zeros(box.shape[0], bool)
    hit[pairs.ravel()] = True
    caps = tr.contact.obstacles.capsules
    if caps.shape[0] and box.shape[0]:
        lo = _obstacle_grid(tr, 2.0 * max(float(ex.max()), float(ey.max()))).query(cx, cy, ex,
                                                                                     ey)
        hit[lo[:, 0]] = True
    return hit, pairs


def contact_advance(tr, stop, max_tries=3):
    """Per-log clocks with contacts: free logs on their own clocks, each island on its own.

    1. Every floating log runs free to ``stop`` (``free_advance``): its swept box.
    2. Logs whose boxes (grown by half a length, the radius and a margin) overlap another
       log's or an obstacle's are the contact set; the connected components of the overlap
       graph are its islands.  The others keep their free motion.
    3. Each island restarts from the interval's start and runs the global clock's contact
       steps among its own logs (``Tracker._global_steps`` on the island): impulses, times of
       impact and the event-driven step of the contact model, as before; an island's next
       contact ends only that island's step.
    4. Closure: if an island's actual sweep reaches a free log's box or another island's
       sweep, those join (one island) and the interval is computed again; after
       ``max_tries``, the whole contact set and the logs it reaches share one step.
    """
    L, C = tr.logs, tr.contact
    t0 = tr.t
    tr._d0_valid = False  # velocities may have been changed by impulses since
    tr._sample_current()
    act0 = tr.act.copy()
    n = act0.size
    S0, face0 = tr.state.copy(), tr.face.copy()
    status0 = L.status[act0].copy()
    kept = _contact_checkpoint(C)
    box = free_advance(tr, stop)
    tr._scatter()
    E_state, E_face, E_F, E_flag = tr.state.copy(), tr.face.copy(), tr.F.copy(), tr.flag.copy()
    # between sub-step ends a centre's path bulges by at most about a tenth of a step (at
    # most length_fraction L long, turning by less than a radian)
    margin = 0.1 * tr.step_options.length_fraction * tr.length + 0.25 * tr.radius
    half = 0.5 * tr.length + tr.radius + margin
    pool_mask, edges = touching(tr, box, half)
    F_end, flag_end = E_F, E_flag
    one_pool = False
    k = islands = 0
    for attempt in range(max_tries + 1):
        if not pool_mask.any():
            break
        sub = np.flatnonzero(pool_mask)
        L.state[act0] = np.where(pool_mask[:, None], S0, E_state)
        L.face[act0] = np.where(pool_mask, face0, E_face)
        L.status[act0] = status0
        F_end, flag_end = E_F.copy(), E_flag.copy()
        labels = (np.where(pool_mask, 0, np.arange(1, n + 1)) if one_pool
                  else island_labels(n, np.ascontiguousarray(edges[:, 0]),
                                     np.ascontiguousarray(edges[:, 1]))[0])
        order = sub[np.argsort(labels[sub], kind="stable")]
        cuts = np.flatnonzero(np.diff(labels[order])) + 1
        swept = np.column_stack([S0[:, 0], S0[:, 1], S0[:, 0], S0[:, 1]])
        active = []
        for group in np.split(order, cuts):  # one island at a time (its own clock)
            pool = act0[group]
            tr.t = t0
            tr._d0_valid = tr._F_valid = False
            _island_start(C, kept)
            tr._set_active(pool)
            sw = swept[group]
            tr._global_steps(stop, None, pool=pool, swept=sw)
            swept[group] = sw
            if tr.act.size:
                tr._scatter()
                tr._sample_current()
                pos = np.searchsorted(act0, tr.act)
                F_end[pos], flag_end[pos] = tr.F, tr.flag
            if isinstance(getattr(C, "_active", None), np.ndarray):
                active.append(C._active)
        if active:
            C._active = np.unique(np.concatenate(active))
        k, islands = sub.size, cuts.size + 1
        # closure: actual sweeps of the islands against the free boxes and each other
        _, pairs = touching_pairs(np.where(pool_mask[:, None], swept, box), half)
        cross = pairs[labels[pairs[:, 0]] != labels[pairs[:, 1]]]
        if cross.size == 0:
            break
        # a deflected path reaches a free log or another island: compute the interval again
        tr.stats["clock_retries"] = tr.stats.get("clock_retries", 0) + 1
        _contact_rollback(C, kept)
        pool_mask[cross.ravel()] = True
        edges = np.vstack([edges, cross])
        if attempt + 1 >= max_tries:  # the last try: every floating log in one island
            pool_mask[:] = True
            one_pool = True
    st = tr.stats
    st["contact_set"] = max(st.get("contact_set", 0), k)
    st["islands"] = st.get("islands", 0) + islands
    final = act0[L.status[act0] == FLOATING]
    tr.t = stop
    tr._d0_valid = tr._F_valid = False
    tr._set_active(final)
    pos = np.searchsorted(act0, final)
    tr.F[:], tr.flag[:] = F_end[pos], flag_end[pos]
    tr._F_valid = True


def _island_start(model, kept):
    """Contact model state at the interval's start, for the next island (its own clock)."""
    _, active = kept
    for name, value in (("_active", active), ("_window", None), ("_bracket", None)):
        if hasattr(model, name):
            setattr(model, name, value)


def _contact_checkpoint(model):
    """What a contact run changes in the contact model besides the logs (hits, caches)."""
    hits = getattr(model, "_hits", None)
    active = getattr(model, "_active", None)
    return (len(hits) if hits is not None else 0,
            active.copy() if isinstance(active, np.ndarray) else active)


def _contact_rollback(model, kept):
    """Forget the hits and caches of a contact run computed again (``contact_advance``)."""
    n_hits, active = kept
    if getattr(model, "_hits", None) is not None:
        del model._hits[n_hits:]
    for name, value in (("_active", active), ("_cache", None), ("_window", None),
                        ("_bracket", None)):
        if hasattr(model, name):
            setattr(model, name, value)


def touching_pairs(box, half):
    """``grid_pairs`` of swept boxes grown by ``half`` (for the closure check)."""
    from driftlog.contact.broadphase import grid_pairs

    cx, cy, ex, ey = _boxes(box, half)
    return None, grid_pairs(cx, cy, ex, ey)
