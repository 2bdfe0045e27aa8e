"""Contacts (issues 5, 15): detection and resolution cost, whole-step cost, contact-time methods.

1. Detection + resolution per step (broad phase, exact narrow phase, impulses) for 1e3, 1e4,
   1e5 logs, sparse (logs 3 lengths apart) and dense (packed 0.12 L apart, so that every log
   has neighbours within its motion), native vs FCL backend (FCL only where it takes under a
   minute: said in the table), 1 and 2 threads; native on a sequence of steps (the logs move
   and bounce) with the broad phase searched afresh at each step and kept between steps
   (issue 15: ``broadphase.PairCache``), the same contacts either way (checked).
1b. Side by side with Box2D (pybox2d 2.3.10) on the same pile of capsule logs with no flow:
   time per step, per touching contact, and momentum/energy drift.
2. Whole sub-step cost with and without contacts: the tracker on a uniform flow (full physics,
   RK4), free step vs event-driven sub-step vs Moreau-Jean step.
3. Contact times: conservative advancement vs the paper's dichotomy on 200 random oblique
   encounters of two turning logs (exact t* by bisection on the exact gap): error of t* and of
   the post-contact velocities against cost (free-motion evaluations per contact), for
   tolerances 1e-1 ... 1e-6 r; and grazing encounters (the log clips a pier within one step
   of the paper's bound) that dichotomy misses.  Chart: contact_accuracy_cost.png.
4. What python-fcl 0.7's collide() and continuousCollide() get wrong for capsules.

    python benchmarks/contact_benchmark.py [--quick]

writes benchmarks/results/contact_*.csv/.md, contact.json and contact_accuracy_cost.png.
"""

import argparse
import functools
import json
import time

import numba
import numpy as np
from _common import RESULTS, machine, write_table

from driftlog.columns import NSTATE, OMEGA, POSITION, THETA, UB, VB, VELOCITY, X, Y
from driftlog.contact import (
    BallisticLogs,
    ContactJamError,
    ContactModel,
    Obstacles,
    native,
    run_contacts,
)
from driftlog.contact.broadphase import grid_pairs
from driftlog.contact.geometry import capsule_gap, log_endpoints
from driftlog.contact.impulses import kinetic_energy, momenta, resolve_islands
from driftlog.contact.toi import motion_margin

L, R = 1.0, 0.05


def field(n, dense, rng):
    """n logs on a square grid: dense 1.12 L apart, sparse 3 L apart; random angles, speeds."""
    g = int(np.ceil(np.sqrt(n)))
    sp = 1.12 * L if dense else 3.0 * L
    xs = np.arange(g) * sp
    gx, gy = np.meshgrid(xs, xs)
    S = np.zeros((n, NSTATE))
    S[:, X], S[:, Y] = gx.ravel()[:n], gy.ravel()[:n]
    S[:, THETA] = rng.uniform(0, np.pi, n)
    S[:, UB:VB + 1] = rng.normal(0, 1.0, (n, 2))
    S[:, OMEGA] = rng.normal(0, 1.0, n)
    return BallisticLogs(S, L, R)


def best_times(fn, repeat=3, min_time=0.2):
    """Best (wall, CPU) seconds per call of ``fn()`` over ``repeat`` runs of at least
    ``min_time`` each (CPU: this process's, which a loaded machine inflates less)."""
    best_w, best_c = np.inf, np.inf
    for _ in range(repeat):
        k = 0
        w0, c0 = time.perf_counter(), time.process_time()
        while True:
            fn()
            k += 1
            w = time.perf_counter() - w0
            if w >= min_time:
                break
        best_w, best_c = min(best_w, w / k), min(best_c, (time.process_time() - c0) / k)
    return best_w, best_c


def detection_step(model, b, dt=0.05, in_place=False):
    """One contact step's detection and resolution (what the event method does per step).

    Returns (candidate pairs, touching contacts, impulses).
    """
    tol = model.tolerance * R
    C = model.detect(b, motion_margin(b.state, b.length, b.radius, dt, tol))
    touch = C.select(C.gap <= tol)
    S = b.state if in_place else b.state.copy()
    imp = np.zeros(len(touch))
    events = resolve_islands(S, 1 / b.mass, 1 / b.inertia, touch.body1, touch.body2,
                             touch.res, 0.5, 1e-12, 10 ** 6, imp)
    return len(C), len(touch), events


class _TimedLogs(BallisticLogs):
    """Force-free logs that time their own free motion (left out of the contact cost)."""

    wall = 0.0
    cpu = 0.0

    def advance(self, dt):
        t0, c0 = time.perf_counter(), time.process_time()
        super().advance(dt)
        self.wall += time.perf_counter() - t0
        self.cpu += time.process_time() - c0


def moving_steps(b0, keep, steps, dt=0.05):
    """``steps`` event-driven sub-steps (conservative advancement, eps 0.5) of the field, the
    broad phase kept between detections or searched afresh at each; wall time of the contact
    work per sub-step (detections, contact times, impulses; the free motion is not timed).
    Returns (seconds per sub-step, detections per sub-step, grid searches, final state,
    simulated seconds)."""
    b = _TimedLogs(b0.state, L, R)
    m = ContactModel(restitution=0.5)
    m.keep_broad_phase = keep
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        m.substep(b, dt)
    wall = time.perf_counter() - t0 - b.wall
    cpu = time.process_time() - c0 - b.cpu
    return (wall / steps, m.stats["detections"] / steps, m.backend.cache.builds, b.state,
            b.t, cpu / steps)


def part_detection(quick, rows):
    rng = np.random.default_rng(1)
    for n in (1_000, 10_000, 100_000):
        for dense in (False, True):
            b = field(n, dense, rng)
            for backend in ("native", "fcl"):
                m = ContactModel(backend=backend)
                for threads in (1, 2):
                    numba.set_num_threads(threads)
                    if backend == "fcl":
                        t0 = time.perf_counter()
                        pairs = detection_step(m, BallisticLogs(b.state[:1000], L, R))
                        est = (time.perf_counter() - t0) * n / 1000
                        if est > (20 if quick else 60) or threads == 2:
                            # python-fcl runs in Python, one pair at a time: no threads
                            rows.append(dict(logs=n, scene="dense" if dense else "sparse",
                                             backend=backend, threads=threads,
                                             candidate_pairs="", ms_per_step="",
                                             us_per_pair="",
                                             note="skipped: single-threaded Python loop"
                                             if threads == 2 else
                                             f"skipped: about {est:.0f} s per step"))
                            continue
                    m.keep_broad_phase = False
                    detection_step(m, b)  # compile, warm up
                    pairs = detection_step(m, b)[0]
                    sec, cpu = best_times(lambda m=m, b=b: detection_step(m, b), repeat=3,
                                          min_time=0.1)
                    rows.append(dict(logs=n, scene="dense" if dense else "sparse",
                                     backend=backend, threads=threads, broad_phase="fresh",
                                     candidate_pairs=pairs, ms_per_step=1e3 * sec,
                                     cpu_ms_per_step=1e3 * cpu,
                                     us_per_pair=1e6 * sec / max(pairs, 1), note=""))
                    print(rows[-1])
                    if backend == "native" and threads == 1:
                        # the hashed grid alone (before issue 15), in the same run
                        native.grid_pairs = functools.partial(grid_pairs, dense=False)
                        sec, cpu = best_times(lambda m=m, b=b: detection_step(m, b),
                                              repeat=3, min_time=0.1)
                        native.grid_pairs = grid_pairs
                        rows.append(dict(logs=n, scene="dense" if dense else "sparse",
                                         backend=backend, threads=threads,
                                         broad_phase="fresh, hashed grid (before)",
                                         candidate_pairs=pairs, ms_per_step=1e3 * sec,
                                         cpu_ms_per_step=1e3 * cpu,
                                         us_per_pair=1e6 * sec / max(pairs, 1), note=""))
                        print(rows[-1])
                    if backend == "native" and dense:
                        steps = 20 if quick or n > 10_000 else 60
                        moving_steps(b, True, 2)  # compile
                        fresh = moving_steps(b, False, steps)
                        kept = moving_steps(b, True, steps)
                        assert np.array_equal(fresh[3], kept[3])  # the same run, bit for bit
                        for name, r in (("fresh, event run", fresh), ("kept, event run", kept)):
                            rows.append(dict(
                                logs=n, scene="dense" if dense else "sparse", backend=backend,
                                threads=threads, broad_phase=name, candidate_pairs="",
                                ms_per_step=1e3 * r[0], cpu_ms_per_step=1e3 * r[5],
                                us_per_pair="",
                                note=f"per sub-step: {steps} sub-steps ({r[4]:.2g} s), "
                                f"{r[1]:.1f} detections each"
                                + (f", grid searched {r[2]} times" if name.startswith("kept")
                                   else "")))
                            print(rows[-1])
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


def part_whole_step(quick, rows):
    from driftlog.analytic import UniformFlow
    from driftlog.logs import Logs
    from driftlog.physics import PhysicsOptions
    from driftlog.tracker import Tracker

    rng = np.random.default_rng(2)
    flow = UniformFlow(1.0, 0.0, depth=2.0)
    for n in (1_000, 10_000) if quick else (1_000, 10_000, 100_000):
        b = field(n, True, rng)
        for mode in ("none", "event", "moreau"):
            logs = Logs(b.state[:, X], b.state[:, Y], b.state[:, THETA], L, R, 700.0)
            contact = None if mode == "none" else ContactModel(method=mode, restitution=0.5)
            tk = Tracker(flow, logs, PhysicsOptions(), contact=contact, t_end=1e3)
            tk._first_check = True
            tk._release()
            tk._update_status()
            steps, sim = 0, 0.0
            t0 = time.perf_counter()
            while time.perf_counter() - t0 < (2.0 if quick else 5.0) and steps < 400:
                dt = min(tk.max_step(), 0.05)
                t_before = tk.t
                if contact is None:
                    tk.advance(dt, have_d0=True)
                else:
                    contact.substep(tk, dt)
                sim += tk.t - t_before
                steps += 1
            wall = time.perf_counter() - t0
            rows.append(dict(logs=n, contact=mode, substeps=steps,
                             ms_per_substep=1e3 * wall / steps, simulated_s=sim,
                             simulated_s_per_wall_s=sim / wall))
            print(rows[-1])


# ----------------------------------------------------------------- Box2D side by side
B2_DT = 1.0 / 60.0
TOUCH = 0.1 * R  # m: a pair is in contact when its exact gap is below this (Box2D's slop)


def touching_pairs(S, deepest=False):
    """Log pairs whose exact capsule gap is below TOUCH (the same count for both engines);
    ``deepest``: also the deepest overlap (m, >= 0)."""
    m = ContactModel()
    m.keep_broad_phase = False
    C = m.detect(BallisticLogs(S, L, R), np.full(S.shape[0], 0.5 * TOUCH))
    k = int(np.count_nonzero(C.gap <= TOUCH))
    if deepest:
        return k, max(0.0, -float(C.gap.min())) if len(C) else 0.0
    return k


def pile(n, rng):
    """A raft of n logs: rows side by side 2 mm apart, ends 2 mm apart, axes along x, random
    velocities of 0.1 m/s and 0.05 rad/s on a slow convergence on the centre (0.2 m/s at the
    edges): every log soon touches its neighbours and the contacts persist."""
    cols = int(np.ceil(np.sqrt(n) / 3.0))
    rows = int(np.ceil(n / cols))
    gx, gy = np.meshgrid(np.arange(cols) * (L + 2 * R + 0.002),
                         np.arange(rows) * (2 * R + 0.002))
    S = np.zeros((n, NSTATE))
    S[:, X], S[:, Y] = gx.ravel()[:n], gy.ravel()[:n]
    c = S[:, X:Y + 1].mean(0)
    half = np.maximum(np.abs(S[:, X:Y + 1] - c).max(0), 1e-9)
    S[:, UB:VB + 1] = -0.2 * (S[:, X:Y + 1] - c) / half + rng.normal(0, 0.1, (n, 2))
    S[:, OMEGA] = rng.normal(0, 0.05, n)
    return S


def invariants(S, mass, inertia):
    """Kinetic energy, linear momentum (2), angular momentum about the origin; and scales
    (sum of |m U|, sum of |m r x U| + |I omega|) the drifts are measured against."""
    e = kinetic_energy(S, mass, inertia)
    px, py, lz = momenta(S, mass, inertia)
    p_scale = float(np.sum(mass * np.hypot(S[:, UB], S[:, VB])))
    l_scale = float(np.sum(np.abs(mass * (S[:, X] * S[:, VB] - S[:, Y] * S[:, UB]))
                           + np.abs(inertia * S[:, OMEGA])))
    return e, np.array([px, py]), lz, p_scale, l_scale


def drifts(before, after):
    e0, p0, l0, ps, ls = before
    e1, p1, l1, _, _ = after
    return dict(energy_change=(e1 - e0) / e0, momentum_drift=float(np.abs(p1 - p0).max()) / ps,
                angular_momentum_drift=abs(l1 - l0) / ls)


def box2d_run(S0, mass, inertia, t_end, eps):
    """The pile in Box2D: each log a body of a box (L x 2r) and two end circles (radius r),
    its mass and inertia set to the log's; no gravity, no friction, no damping, no sleep;
    steps of 1/60 s with 8 velocity and 3 position iterations (Box2D's defaults)."""
    import Box2D as b2

    world = b2.b2World(gravity=(0, 0), doSleep=False)
    bodies = []
    for k in range(S0.shape[0]):
        body = world.CreateDynamicBody(position=(S0[k, X], S0[k, Y]), angle=S0[k, THETA],
                                       linearDamping=0.0, angularDamping=0.0)
        kw = dict(friction=0.0, restitution=eps, density=1.0)
        body.CreateFixture(b2.b2FixtureDef(shape=b2.b2PolygonShape(box=(0.5 * L, R)), **kw))
        for e in (-0.5 * L, 0.5 * L):
            body.CreateFixture(b2.b2FixtureDef(shape=b2.b2CircleShape(pos=(e, 0), radius=R),
                                               **kw))
        body.massData = b2.b2MassData(mass=float(mass[k]), center=(0, 0), I=float(inertia[k]))
        body.linearVelocity = (S0[k, UB], S0[k, VB])
        body.angularVelocity = S0[k, OMEGA]
        bodies.append(body)

    def state():
        S = np.zeros_like(S0)
        for k, body in enumerate(bodies):
            S[k, X], S[k, Y] = body.position
            S[k, THETA] = body.angle
            S[k, UB], S[k, VB] = body.linearVelocity
            S[k, OMEGA] = body.angularVelocity
        return S

    steps = int(round(t_end / B2_DT))
    world.Step(B2_DT, 8, 3)  # the first step builds the contact list (timed apart)
    S1 = state()
    wall, cpu, touching, pairs = 0.0, 0.0, 0, 0
    for _ in range(steps - 1):
        t0, c0 = time.perf_counter(), time.process_time()
        world.Step(B2_DT, 8, 3)
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        pairs += world.contactCount
        touching += touching_pairs(state())
    return dict(steps=steps - 1, wall=wall, cpu=cpu, pairs=pairs, touching=touching,
                S_start=S1,
                S_end=state(), simulated=(steps - 1) * B2_DT)


def driftlog_run(S_start, mass, inertia, t_end, eps, method, iterations=200):
    """The same pile in driftlog: force-free logs, ``method`` contacts, steps of at most 1/60 s
    (Moreau-Jean shortens them near contacts to a quarter radius of motion, and sweeps at
    most ``iterations`` times; the event method ends them at each contact)."""
    b = BallisticLogs(S_start, L, R)
    b.mass, b.inertia = mass.copy(), inertia.copy()
    m = ContactModel(method=method, restitution=eps, rest_speed=0.0, iterations=iterations)
    m.check_overlap = False
    steps, wall, cpu, touching = 0, 0.0, 0.0, 0
    while b.t < t_end - 1e-12:
        t0, c0 = time.perf_counter(), time.process_time()
        m.substep(b, min(B2_DT, t_end - b.t))
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        steps += 1
        touching += touching_pairs(b.state)
    return dict(steps=steps, wall=wall, cpu=cpu, touching=touching, S_end=b.state.copy(),
                simulated=b.t, min_gap=m.stats["min_gap"], pairs=np.nan,
                advances=b.advances)


def part_box2d(quick, rows, sizes=(1_000, 10_000)):
    for n in sizes:
        rng = np.random.default_rng(5)
        # 1e4 logs: 0.25 s, 8 sweeps only (200 sweeps: minutes per simulated second here)
        t_end = (0.5 if quick else 1.0) if n <= 1_000 else 0.25
        S0 = pile(n, rng)
        b = BallisticLogs(S0, L, R)
        mass, inertia = b.mass, b.inertia
        for eps in (1.0, 0.5) if n <= 1_000 else (1.0,):
            ref = box2d_run(S0, mass, inertia, t_end + B2_DT, eps)
            inv0 = invariants(ref["S_start"], mass, inertia)
            runs = [("Box2D 2.3.10 (8 + 3 iterations)", ref)]
            numba.set_num_threads(1)
            for method, its in (("moreau", 8), ("moreau", 200), ("event", 0)):
                if n > 1_000 and its != 8:
                    continue
                name = f"driftlog {method}" + (f" ({its} sweeps)" if its else "")
                driftlog_run(ref["S_start"][:50], mass[:50], inertia[:50], 0.05, eps, method)
                try:
                    runs.append((name, driftlog_run(ref["S_start"], mass, inertia, t_end, eps,
                                                    method, its or 200)))
                except ContactJamError as e:
                    rows.append(dict(logs=n, restitution=eps, engine=name,
                                     steps=f"stopped: {str(e)[:60]}..."))
                    print(rows[-1])
            for name, r in runs:
                d = drifts(inv0, invariants(r["S_end"], mass, inertia))
                d["deepest_overlap_mm"] = 1e3 * touching_pairs(r["S_end"], deepest=True)[1]
                rows.append(dict(
                    logs=n, restitution=eps, engine=name, steps=r["steps"],
                    simulated_s=r["simulated"], ms_per_step=1e3 * r["wall"] / r["steps"],
                    cpu_ms_per_step=1e3 * r["cpu"] / r["steps"],
                    touching_per_step=r["touching"] / r["steps"],
                    us_per_contact=1e6 * r["wall"] / max(r["touching"], 1),
                    cpu_us_per_contact=1e6 * r["cpu"] / max(r["touching"], 1),
                    wall_s_per_simulated_s=r["wall"] / r["simulated"], **d))
                print(rows[-1])
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


# ----------------------------------------------------------------- contact times
def encounters(k, rng):
    """k random oblique encounters of two turning logs that do touch (exact t* by bisection)."""
    out = []
    while len(out) < k:
        S = np.zeros((2, NSTATE))
        S[0, THETA:] = [rng.uniform(0, np.pi), *rng.normal(0, 0.5, 2), rng.normal(0, 0.5)]
        ang = rng.uniform(0, 2 * np.pi)
        S[1, X:Y + 1] = 2.0 * np.array([np.cos(ang), np.sin(ang)])
        S[1, THETA] = rng.uniform(0, np.pi)
        S[1, UB:VB + 1] = -0.8 * S[1, X:Y + 1] / 2.0 + rng.normal(0, 0.2, 2)
        S[1, OMEGA] = rng.normal(0, 0.5)
        t_star = first_contact(S, 4.0)
        if t_star is not None and t_star > 0.2:
            out.append((S, t_star))
    return out


def gap_at(S, t):
    P = S[:, POSITION] + t * S[:, VELOCITY]
    return capsule_gap(*log_endpoints(*P[0], L), R, *log_endpoints(*P[1], L), R, np.empty(5))


def first_contact(S, t_end):
    ts = np.linspace(0, t_end, 4001)
    g = np.array([gap_at(S, t) for t in ts])
    k = np.flatnonzero(g <= 0)
    if k.size == 0:
        return None
    lo, hi = ts[k[0] - 1], ts[k[0]]
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap_at(S, mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def exact_after(S, t_star, eps):
    """Post-contact velocities, the impulse at the exact contact time (docs/model.md eq. (50))."""
    b = BallisticLogs(S, L, R)
    b.advance(t_star)
    out = np.empty(5)
    capsule_gap(*log_endpoints(*b.state[0, :3], L), R, *log_endpoints(*b.state[1, :3], L), R,
                out)
    from driftlog.contact.impulses import pair_impulse

    pair_impulse(b.state, 1 / b.mass, 1 / b.inertia, 0, 1, out[1], out[2], out[3], out[4], eps,
                 0.0)
    return b.state[:, VELOCITY].copy()


def part_contact_times(quick, rows):
    rng = np.random.default_rng(3)
    cases = encounters(60 if quick else 200, rng)
    eps = 0.8
    refs = [exact_after(S, t, eps) for S, t in cases]
    for toi in ("conservative", "dichotomy"):
        for tol in (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
            errs_t, errs_v, adv, wall, missed = [], [], 0, 0.0, 0
            for (S, t_star), ref in zip(cases, refs, strict=True):
                b = BallisticLogs(S, L, R)
                m = ContactModel(restitution=eps, time_of_impact=toi, tolerance=tol,
                                 rest_speed=0.0)
                t0 = time.perf_counter()
                while b.t < t_star + 0.3:
                    m.substep(b, min(b.max_step(), t_star + 0.3 - b.t))
                    h = m._hits
                    if h:
                        break
                wall += time.perf_counter() - t0
                adv += b.advances
                hits = m.drain_hits()
                if len(hits["time"]) == 0:
                    missed += 1
                    continue
                errs_t.append(abs(hits["time"][0] - t_star))
                errs_v.append(np.abs(b.state[:, VELOCITY] - ref).max())
            rows.append(dict(method=toi, tolerance=tol, encounters=len(cases), missed=missed,
                             t_error_median=float(np.median(errs_t)),
                             t_error_max=float(np.max(errs_t)),
                             velocity_error_median=float(np.median(errs_v)),
                             velocity_error_max=float(np.max(errs_v)),
                             advances_per_contact=adv / len(cases),
                             ms_per_contact=1e3 * wall / len(cases)))
            print(rows[-1])


def part_grazing(rows):
    """A log broadside at 1 m/s past a pier it clips by `depth`, paper's step bound."""
    for depth in (0.01, 0.05, 0.1, 0.2):
        for toi in ("conservative", "dichotomy"):
            found = 0
            offsets = np.linspace(0, 1, 20, endpoint=False)
            for off in offsets:  # where, within a step, the log passes the pier
                obs = Obstacles()
                obs.add_circle([off, 0.5 + R + 0.3 - depth], 0.3, "pier")
                b = BallisticLogs(np.array([[-0.45, 0.0, np.pi / 2, 1.0, 0.0, 0.0]]), L, R)
                m = ContactModel(obs, restitution=1.0, time_of_impact=toi)
                run_contacts(m, b, 3.0)
                found += len(m.drain_hits()["time"]) > 0
            rows.append(dict(clip_depth_m=depth, method=toi, encounters=len(offsets),
                             found=found, missed=len(offsets) - found))
            print(rows[-1])


def chart(rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for toi, mk in (("conservative", "o-"), ("dichotomy", "s--")):
        r = [x for x in rows if x["method"] == toi]
        cost = [x["advances_per_contact"] for x in r]
        axes[0].loglog(cost, [x["t_error_median"] for x in r], mk, label=f"{toi} (median)")
        axes[0].loglog(cost, [x["t_error_max"] for x in r], mk, alpha=0.4, label=f"{toi} (max)")
        axes[1].loglog(cost, [x["velocity_error_median"] for x in r], mk, label=f"{toi} (median)")
        axes[1].loglog(cost, [x["velocity_error_max"] for x in r], mk, alpha=0.4,
                       label=f"{toi} (max)")
        for x in r:
            axes[0].annotate(f"{x['tolerance']:.0e}", (x["advances_per_contact"],
                                                       x["t_error_median"]), fontsize=6)
    axes[0].set(xlabel="free-motion evaluations per contact", ylabel="|t - t*| (s)",
                title="contact time")
    axes[1].set(xlabel="free-motion evaluations per contact",
                ylabel="post-contact velocity error (m/s, rad/s)", title="velocities after")
    for a in axes:
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    fig.suptitle("Contact-time methods: accuracy vs cost (labels: tolerance / r)")
    fig.tight_layout()
    fig.savefig(RESULTS / "contact_accuracy_cost.png", dpi=120)


def fcl_note():
    """collide() depths/normals and continuousCollide() on capsules, against exact values."""
    import fcl

    from driftlog.contact.fcl_backend import log_object

    rng = np.random.default_rng(4)
    req = fcl.CollisionRequest(enable_contact=True, num_max_contacts=4)
    depth_err, ang_err = [], []
    for _ in range(1000):
        S = np.zeros((2, 3))
        S[:, THETA] = rng.uniform(0, np.pi, 2)
        S[1, X:Y + 1] = rng.uniform(-0.3, 0.3, 2)
        out = np.empty(5)
        gap = capsule_gap(*log_endpoints(*S[0], L), R, *log_endpoints(*S[1], L), R, out)
        res = fcl.CollisionResult()
        if not fcl.collide(log_object(*S[0], L, R), log_object(*S[1], L, R), req, res):
            continue
        c = res.contacts[0]
        depth_err.append(abs(c.penetration_depth + gap) / -gap)
        n = -np.asarray(c.normal)[:2]  # FCL: from 1 to 2
        n /= max(np.hypot(*n), 1e-300)
        ang_err.append(np.degrees(np.arccos(np.clip(n @ out[1:3], -1, 1))))
    missed = 0
    for _ in range(100):
        y0 = rng.uniform(0.5, 1.5)
        a = log_object(0, 0, 0, L, R)
        b = log_object(rng.uniform(-0.3, 0.3), y0, rng.uniform(-0.3, 0.3), L, R)
        cres = fcl.ContinuousCollisionResult()
        fcl.continuousCollide(a, a.getTransform(), b,
                              fcl.Transform(b.getRotation(), b.getTranslation() - [0, 2 * y0, 0]),
                              fcl.ContinuousCollisionRequest(), cres)
        missed += not cres.is_collide
    d, a = np.array(depth_err), np.array(ang_err)
    return dict(fcl_version=getattr(fcl, "__version__", "0.7"),
                collide_pairs=int(d.size),
                collide_depth_relative_error_median=float(np.median(d)),
                collide_depth_error_over_10pc=float(np.mean(d > 0.1)),
                collide_normal_error_deg_median=float(np.median(a)),
                collide_normal_error_over_10deg=float(np.mean(a > 10)),
                continuous_collide_crossings=100, continuous_collide_missed=int(missed))


PARTS = ("detection", "box2d", "step", "times", "grazing", "fcl")


def run(quick, parts=PARTS):
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "contact.json"
    out = json.loads(path.read_text()) if path.exists() and set(parts) != set(PARTS) else {}
    out["machine"] = machine()
    if "detection" in parts:
        rows = []
        part_detection(quick, rows)
        write_table("contact_detection", rows, ["logs", "scene", "backend", "threads",
                                                "broad_phase", "candidate_pairs", "ms_per_step",
                                                "cpu_ms_per_step", "us_per_pair", "note"],
                    "Contact detection + resolution per step",
                    "Broad phase (grid), exact narrow phase and impulses of one step; logs "
                    f"L = {L} m, r = {R} m, random angles and speeds ~1 m/s; margin = motion "
                    "over 0.05 s. fresh: one step, the grid searched; event run: sub-steps of "
                    "the event-driven method (eps 0.5) on the same field, the broad phase "
                    "searched at each detection or kept between them. Re-create: `python "
                    "benchmarks/contact_benchmark.py`.")
        out["detection"] = rows
    if "box2d" in parts:
        rows_b2 = []
        part_box2d(quick, rows_b2)
        write_table("contact_box2d", rows_b2, ["logs", "restitution", "engine", "steps",
                                               "simulated_s", "ms_per_step", "cpu_ms_per_step",
                                               "touching_per_step", "us_per_contact",
                                               "cpu_us_per_contact",
                                               "wall_s_per_simulated_s", "energy_change",
                                               "momentum_drift", "angular_momentum_drift",
                                               "deepest_overlap_mm"],
                    "Side by side with Box2D: a pile of capsule logs, no flow",
                    f"A raft of logs L = {L} m, r = {R} m (rows side by side 2 mm apart, axes "
                    "along x, random velocities 0.1 m/s on a convergence of 0.2 m/s at the "
                    "edges: `pile`), no gravity, friction or damping; 1 thread. Box2D: steps "
                    "of 1/60 s, 8 velocity + 3 position iterations, capsules as a box and two "
                    "circles, the logs' masses and inertias; collisions slower than "
                    "b2_velocityThreshold = 1 m/s do not bounce (Box2D's rule). driftlog: the "
                    "same start state (after Box2D's first step), steps of at most 1/60 s; "
                    "Moreau-Jean with at most 8 (as Box2D) or 200 (the default) Gauss-Seidel "
                    "sweeps per solve. Touching: log pairs whose "
                    f"exact gap is below {TOUCH} m at the end of a step, in both engines. "
                    "Drifts relative to the sum of |m U| (momentum) and of |m r x U| + "
                    "|I omega| (angular momentum).")
        out["box2d"] = rows_b2
    if "step" in parts:
        rows2 = []
        part_whole_step(quick, rows2)
        write_table("contact_step", rows2, ["logs", "contact", "substeps", "ms_per_substep",
                                            "simulated_s", "simulated_s_per_wall_s"],
                    "Whole sub-step with and without contacts (tracker, uniform flow, full "
                    "physics, RK4, dense logs)",
                    "event: each sub-step ends at the next contact of any pair, so sub-steps "
                    "shrink as logs multiply; moreau: one step of at most 0.05 s whatever the "
                    "contacts.")
        out["step"] = rows2
    if "times" in parts:
        rows3 = []
        part_contact_times(quick, rows3)
        write_table("contact_times", rows3, ["method", "tolerance", "encounters", "missed",
                                             "t_error_median", "t_error_max",
                                             "velocity_error_median", "velocity_error_max",
                                             "advances_per_contact", "ms_per_contact"],
                    "Contact times: conservative advancement vs dichotomy",
                    "Random oblique encounters of two turning logs (force-free); tolerance "
                    "relative to r; t* exact by bisection on the exact gap; velocities against "
                    "the impulse at t*.")
        chart(rows3)
        out["contact_times"] = rows3
    if "grazing" in parts:
        rows4 = []
        part_grazing(rows4)
        write_table("contact_grazing", rows4, ["clip_depth_m", "method", "encounters", "found",
                                               "missed"],
                    "Grazing contacts with the paper's step bound (L / |U|)",
                    "A log broadside at 1 m/s clips a pier (r 0.3 m) by the given depth, at 20 "
                    "positions within a step.")
        out["grazing"] = rows4
    if "fcl" in parts:
        out["fcl"] = fcl_note()
        print(out["fcl"])
    path.write_text(json.dumps(out, indent=1, default=str))


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="fewer encounters, shorter runs")
    p.add_argument("--parts", default=",".join(PARTS),
                   help=f"comma-separated parts to run, of {', '.join(PARTS)} (default all; "
                   "the others' results in contact.json are kept)")
    a = p.parse_args()
    parts = [x.strip() for x in a.parts.split(",") if x.strip()]
    bad = [x for x in parts if x not in PARTS]
    if bad:
        p.error(f"--parts: {', '.join(bad)} not among {', '.join(PARTS)}")
    run(a.quick, parts)
