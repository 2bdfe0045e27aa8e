"""What one member leaves for the aggregate: faces its logs passed, first arrivals, fates, hits.

A ``MemberRecorder`` takes the place of the trajectory writer in ``driftlog.api.track`` (the
same interface: ``record``, ``hits``, ``flush``, ``set_attrs``, ``close``) and reduces the
records as they come, so a member needs no trajectory file; ``summarize_trajectories`` (in
``driftlog.ensemble.runner``, which rebuilds the logs from the stored scenario) replays
a trajectory file through the same recorder, so a member run on its own (``driftlog track``)
summarizes to the same numbers, bit for bit.

Faces a log passes.  Between two records a log is taken to move on the straight segment from
the first position to the second; the segment is walked across the mesh face by face
(Cyrus-Beck clipping of the segment against each convex face, leaving by the edge where it
exits first), so a fast log that crosses several faces between records marks all of them,
and the time it enters each face is interpolated linearly along the segment.  The first
segment starts at the log's release point and time.  Where the walk meets the boundary of the
mesh before the end of the segment (the log left the domain, or cut across a bend or an island
between records), the faces beyond are not swept: the end point is located and marked alone.
The walk is exact for the straight segment; the log's curved path between records is not
(keep ``time.output_interval`` short against the time a log takes to cross a face).

Fates.  A log's last recorded status: stranded (dry) and resting (too shallow to float) logs
are kept with their final position and face (stranding locations).

Hits.  Contact hits (``hit_other`` < 0: obstacle ``-(other + 1)``, named in the trajectory
file's ``obstacle_names``) are counted per obstacle, with the number of distinct logs that hit.

Held obstacles (for the clogging odds).  At every record, an obstacle is *occupied* when at
least one log that is not waiting or gone (floating, resting or stranded) lies within
``blocked_gap`` x its radius of one of the obstacle's capsules (the exact capsule-capsule gap
of ``driftlog.contact.geometry``, the log's axis from its recorded x, y, theta).  The member
keeps, per obstacle, the longest run of consecutive records at which it was occupied, as the
time from the first to the last record of the run (``obstacle_held``, seconds; a single
record is 0 s); the aggregate calls the obstacle *blocked* in the member when that span is at
least ``[ensemble] blocked_after``.  Occupancy is sampled at the records, so a contact broken
and made again between two records counts as held (keep ``time.output_interval`` short
against ``blocked_after``).  The mesh's walls are not checked (a log against a bank is
stranding, not clogging): their span is NaN.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numba as nb
import numpy as np

from driftlog.contact.geometry import NRES, capsule_gap, log_endpoints
from driftlog.locate import locate_one
from driftlog.logs import LEFT, RESTING, STRANDED, WAITING

__all__ = ["MemberSummary", "MemberRecorder", "sweep_segments", "METHOD"]

METHOD = ("faces passed: each log's path between records is the straight segment between its "
          "positions (from its release point), walked face by face across the mesh; entry "
          "times interpolated linearly along it; beyond a boundary met before the segment "
          "ends, only the end point is located")

MAX_WALK = 1_000_000  # faces crossed by one segment before the walk gives up


# --------------------------------------------------------------------- kernels
@nb.njit(cache=True)
def _sweep(start, log, xa, ya, ta, fa, xb, yb, tb, fb, n_faces, keys, times, n_out, loc):
    """Walk segments i >= start across the mesh; append (log, face) keys with entry times.

    Returns (n_out, i): i == log.size when done, else the segment where the buffers filled up
    (its entries so far are kept; redoing it appends duplicates, which ``_compact`` merges).
    """
    cap = keys.shape[0]
    face_nodes, face_n, face_nbr = loc.face_nodes, loc.face_n, loc.face_nbr
    node_x, node_y = loc.node_x, loc.node_y
    for i in range(start, log.size):
        f = fa[i]
        locate_end = f < 0  # start unknown (outside): mark where the segment ends
        dx, dy = xb[i] - xa[i], yb[i] - ya[i]
        s = 0.0
        for _ in range(MAX_WALK if not locate_end and (dx != 0.0 or dy != 0.0) else 0):
            smin = np.inf
            kmin = -1
            n = face_n[f]
            for k in range(n):  # Cyrus-Beck: the exit is the first edge line crossed outwards
                a = face_nodes[f, k]
                b = face_nodes[f, (k + 1) % n]
                ex, ey = node_x[b] - node_x[a], node_y[b] - node_y[a]
                cd = ex * dy - ey * dx
                if cd < 0.0:
                    se = -(ex * (ya[i] - node_y[a]) - ey * (xa[i] - node_x[a])) / cd
                    if se < smin:
                        smin = se
                        kmin = k
            if kmin < 0 or smin >= 1.0:
                break  # the segment ends in f
            g = face_nbr[f, kmin]
            if g < 0:  # meets the boundary: locate the end alone
                locate_end = True
                break
            s = max(s, smin)
            if n_out >= cap:
                return n_out, i
            keys[n_out] = log[i] * n_faces + g
            times[n_out] = ta[i] + s * (tb[i] - ta[i])
            n_out += 1
            f = g
        if locate_end:
            f = locate_one(xb[i], yb[i], -1, loc)
            if f >= 0:
                if n_out >= cap:
                    return n_out, i
                keys[n_out] = log[i] * n_faces + f
                times[n_out] = tb[i]
                n_out += 1
        fb[i] = f
    return n_out, log.size


@nb.njit(cache=True)
def _compact(keys, times, n):
    """Sort the first n keys, keep each once with its earliest time; returns the new count."""
    k = keys[:n].copy()
    t = times[:n].copy()
    order = np.argsort(k, kind="mergesort")
    m = 0
    for j in range(n):
        o = order[j]
        if m > 0 and keys[m - 1] == k[o]:
            if t[o] < times[m - 1]:
                times[m - 1] = t[o]
        else:
            keys[m] = k[o]
            times[m] = t[o]
            m += 1
    return m


@nb.njit(cache=True)
def _per_face(keys, times, n, n_faces):
    """From unique (log, face) keys: the faces passed, logs per face, earliest entry per face."""
    count = np.zeros(n_faces, np.int32)
    first = np.full(n_faces, np.inf)
    for j in range(n):
        f = keys[j] % n_faces
        count[f] += 1
        if times[j] < first[f]:
            first[f] = times[j]
    faces = np.flatnonzero(count)
    return faces.astype(np.int64), count[faces], first[faces]


def sweep_segments(mesh, log, xa, ya, ta, fa, xb, yb, tb):
    """Faces crossed by straight segments (a -> b) of logs ``log``; see the module docstring.

    Returns (keys, times, fb): unique keys ``log * n_faces + face`` with the earliest entry
    time, and the face of each segment's end (-1 outside).
    """
    buf = _Entries(mesh.n_faces)
    fb = buf.sweep(mesh, log, xa, ya, ta, fa, xb, yb, tb)
    n = buf.compact()
    return buf.keys[:n].copy(), buf.times[:n].copy(), fb


class _Entries:
    """Growable buffers of (log, face) keys and entry times, compacted when full."""

    def __init__(self, n_faces, capacity=4096):
        self.n_faces = int(n_faces)
        self.keys = np.empty(capacity, np.int64)
        self.times = np.empty(capacity)
        self.n = 0

    def append(self, keys, times):
        k = keys.size
        if self.n + k > self.keys.size:
            self.compact()
            self._grow(self.n + k)
        self.keys[self.n:self.n + k] = keys
        self.times[self.n:self.n + k] = times
        self.n += k

    def _grow(self, need):
        if need > self.keys.size // 2:  # keep room after compaction: amortised O(1)
            size = max(2 * need, 2 * self.keys.size)
            self.keys = np.concatenate([self.keys[:self.n], np.empty(size - self.n, np.int64)])
            self.times = np.concatenate([self.times[:self.n], np.empty(size - self.n)])

    def compact(self):
        self.n = _compact(self.keys, self.times, self.n)
        return self.n

    def sweep(self, mesh, log, xa, ya, ta, fa, xb, yb, tb):
        c = np.ascontiguousarray
        log, fa = c(log, np.int64), c(fa, np.int64)
        xa, ya, ta, xb, yb, tb = (c(a, np.float64) for a in (xa, ya, ta, xb, yb, tb))
        fb = np.empty(log.size, np.int64)
        i = 0
        while True:
            self.n, i = _sweep(i, log, xa, ya, ta, fa, xb, yb, tb, fb, self.n_faces,
                               self.keys, self.times, self.n, mesh.locator())
            if i >= log.size:
                return fb
            self.compact()
            self._grow(self.n + 1)


@nb.njit(cache=True)
def _occupied(x, y, theta, length, radius, status, caps, owner, box, gap_rel, occ):
    """Mark ``occ[k]`` for every obstacle k within gap_rel * r of a log (see module docstring).

    ``box`` (n_obstacles, 4): each obstacle's bounding box, grown by nothing (the logs'
    reach is added here); obstacles already marked are skipped.
    """
    out = np.empty(NRES)
    for i in range(x.size):
        if status[i] == WAITING or status[i] == LEFT:
            continue
        r = radius[i]
        reach = 0.5 * length[i] + r * (1.0 + gap_rel)
        ax, ay, bx, by = log_endpoints(x[i], y[i], theta[i], length[i])
        for j in range(caps.shape[0]):
            k = owner[j]
            if occ[k]:
                continue
            if (x[i] + reach < box[k, 0] or x[i] - reach > box[k, 2]
                    or y[i] + reach < box[k, 1] or y[i] - reach > box[k, 3]):
                continue
            g = capsule_gap(ax, ay, bx, by, r, caps[j, 0], caps[j, 1], caps[j, 2],
                            caps[j, 3], caps[j, 4], out)
            if g <= gap_rel * r:
                occ[k] = True


def obstacle_boxes(capsules, owner, n):
    """Bounding boxes (n, 4: x0, y0, x1, y1) of the obstacles made of ``capsules``."""
    c = np.asarray(capsules, float).reshape(-1, 5)
    box = np.empty((n, 4))
    box[:, :2], box[:, 2:] = np.inf, -np.inf
    lo = np.minimum(c[:, :2], c[:, 2:4]) - c[:, 4:5]
    hi = np.maximum(c[:, :2], c[:, 2:4]) + c[:, 4:5]
    np.minimum.at(box[:, 0], owner, lo[:, 0])
    np.minimum.at(box[:, 1], owner, lo[:, 1])
    np.maximum.at(box[:, 2], owner, hi[:, 0])
    np.maximum.at(box[:, 3], owner, hi[:, 1])
    return box


# --------------------------------------------------------------------- per member
@dataclass
class MemberSummary:
    """One member, reduced: what the aggregate adds up.  Arrays are small (faces passed)."""

    member: int
    n_faces: int
    n_logs: int
    faces: np.ndarray  # faces passed by at least one log
    face_logs: np.ndarray  # logs that passed each of them
    face_arrival: np.ndarray  # earliest entry time (s)
    status_counts: np.ndarray  # final status of the logs (WAITING ... LEFT)
    idle_x: np.ndarray  # final positions of stranded and resting logs
    idle_y: np.ndarray
    idle_status: np.ndarray
    idle_face: np.ndarray
    obstacle_names: list
    obstacle_hits: np.ndarray  # hit events per obstacle
    obstacle_logs: np.ndarray  # distinct logs that hit each obstacle
    log_log_hits: int = 0
    obstacle_held: np.ndarray = None  # longest span occupied by a log (s); NaN: not checked
    parameters: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)  # physics level, wall seconds, sub-steps

    def to_npz(self, path) -> Path:
        """Write atomically (temporary file, fsync, rename): a file that exists is complete."""
        path = Path(path)
        tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
        arrays = {k: getattr(self, k) for k in ("faces", "face_logs", "face_arrival",
                                                "status_counts", "idle_x", "idle_y",
                                                "idle_status", "idle_face", "obstacle_hits",
                                                "obstacle_logs")}
        if self.obstacle_held is not None:
            arrays["obstacle_held"] = np.asarray(self.obstacle_held, float)
        if self.n_faces < 2**31:  # a quarter smaller on disk
            arrays["faces"] = arrays["faces"].astype(np.int32)
        meta = dict(member=self.member, n_faces=self.n_faces, n_logs=self.n_logs,
                    obstacle_names=list(self.obstacle_names), log_log_hits=self.log_log_hits,
                    parameters=self.parameters, info=self.info)
        with open(tmp, "wb") as f:
            np.savez(f, meta=np.array(json.dumps(meta, default=_json_default)), **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        return path

    @classmethod
    def from_npz(cls, path) -> MemberSummary:
        """Read a summary written by ``to_npz``."""
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            arrays = {k: z[k] for k in z.files if k != "meta"}
        arrays["faces"] = arrays["faces"].astype(np.int64)
        return cls(**meta, **arrays)


def _json_default(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)


class MemberRecorder:
    """Reduce a member's records as the tracker makes them (the TrajectoryWriter interface).

    Parameters
    ----------
    mesh : Mesh
        The mesh the faces are counted on (the flow mesh, or an aggregation grid).
    logs : Logs
        The member's logs before the run (their seeded positions are the release points).
    t_start : float
        Start of the run: logs with an earlier release time are released then.
    obstacle_names : sequence of str
    inner : TrajectoryWriter, optional
        Also write the trajectory file (records and hits are passed on).
    obstacles : Obstacles, optional
        The obstacles' geometry (``[[obstacles]]``, in the order of ``obstacle_names``; walls,
        which come last, left out): the held spans of the module docstring are measured.
    blocked_gap : float
        A log within this share of its radius of an obstacle occupies it.
    """

    def __init__(self, mesh, logs, t_start, obstacle_names=(), inner=None, obstacles=None,
                 blocked_gap=0.1):
        self.mesh = mesh
        self.inner = inner
        n = len(logs)
        self.n_logs = n
        self.release_x = logs.x.copy()
        self.release_y = logs.y.copy()
        self.release_t = np.maximum(np.asarray(logs.release_time, float), float(t_start))
        self.last_x = np.zeros(n)
        self.last_y = np.zeros(n)
        self.last_t = np.zeros(n)
        self.last_face = np.full(n, -1, np.int64)
        self.started = np.zeros(n, bool)
        self.status = np.full(n, WAITING, np.int8)
        self.entries = _Entries(mesh.n_faces)
        self.obstacle_names = unique_names(obstacle_names)
        self.obstacle_hits = np.zeros(len(self.obstacle_names), np.int64)
        self.log_hit = np.zeros((n, len(self.obstacle_names)), bool)
        self.log_log_hits = 0
        self.path = getattr(inner, "path", None)
        # held obstacles: geometry of the checked ones, current run start, longest span
        self.length = np.ascontiguousarray(logs.length, float)
        self.radius = np.ascontiguousarray(logs.radius, float)
        self.blocked_gap = float(blocked_gap)
        n_obs = len(obstacles.names) if obstacles is not None else 0
        if obstacles is not None and len(obstacles.capsules):
            self.caps = np.ascontiguousarray(obstacles.capsules, float)
            self.owner = np.ascontiguousarray(obstacles.owner, np.int64)
        else:
            self.caps, self.owner = np.zeros((0, 5)), np.zeros(0, np.int64)
        self.box = obstacle_boxes(self.caps, self.owner, n_obs)
        self.held = np.full(len(self.obstacle_names), np.nan)
        self.held[:n_obs] = 0.0
        self.n_checked = n_obs
        self.run_start = np.full(n_obs, np.nan)
        self.occ = np.zeros(n_obs, bool)
        self.occ_t = None  # time of the record being gathered (one time may come in parts)

    # ----------------------------------------------------------------- writer interface
    def record(self, t, index, columns):
        """One record: logs ``index`` at time t (columns x, y, status, ...)."""
        if self.inner is not None:
            self.inner.record(t, index, columns)
        idx = np.asarray(index, np.int64)
        if idx.size == 0:
            return
        new = idx[~self.started[idx]]
        if new.size:  # first record of these logs: start from the release point
            f = self.mesh.locate(self.release_x[new], self.release_y[new])
            inside = f >= 0
            self.entries.append(new[inside] * self.entries.n_faces + f[inside],
                                self.release_t[new[inside]])
            self.last_x[new], self.last_y[new] = self.release_x[new], self.release_y[new]
            self.last_t[new], self.last_face[new] = self.release_t[new], f
            self.started[new] = True
        x = np.asarray(columns["x"], float)
        y = np.asarray(columns["y"], float)
        tb = np.full(idx.size, float(t))
        fb = self.entries.sweep(self.mesh, idx, self.last_x[idx], self.last_y[idx],
                                self.last_t[idx], self.last_face[idx], x, y, tb)
        self.last_x[idx], self.last_y[idx], self.last_t[idx], self.last_face[idx] = x, y, tb, fb
        self.status[idx] = columns["status"]
        if self.n_checked:
            self._occupy(float(t), idx, x, y, columns)

    def _occupy(self, t, idx, x, y, columns):
        if self.occ_t is not None and t != self.occ_t:
            self._close_record()
        self.occ_t = t
        theta = np.ascontiguousarray(columns["theta"], float)
        _occupied(x, y, theta, self.length[idx], self.radius[idx],
                  np.ascontiguousarray(columns["status"], np.int8), self.caps, self.owner,
                  self.box, self.blocked_gap, self.occ)

    def _close_record(self):
        """The record at ``occ_t`` is complete: extend or end the occupied runs."""
        t, occ = self.occ_t, self.occ
        start = self.run_start
        start[occ & np.isnan(start)] = t
        start[~occ] = np.nan
        n = self.n_checked
        self.held[:n] = np.fmax(self.held[:n], np.where(occ, t - start, 0.0))
        occ[:] = False
        self.occ_t = None

    def hits(self, hits: dict):
        """Contact hits: dict of arrays time, log_id, other, impulse, x, y."""
        if self.inner is not None:
            self.inner.hits(hits)
        other = np.asarray(hits.get("other", ()), np.int64)
        if other.size == 0:
            return
        log = np.asarray(hits["log_id"], np.int64)
        ob = other < 0
        k = -other[ob] - 1
        if k.size and k.max() >= len(self.obstacle_names):  # unnamed obstacles: number them
            extra = int(k.max()) + 1 - len(self.obstacle_names)
            self.obstacle_names += [f"obstacle_{len(self.obstacle_names) + j}"
                                    for j in range(extra)]
            self.obstacle_hits = np.concatenate([self.obstacle_hits, np.zeros(extra, np.int64)])
            self.log_hit = np.hstack([self.log_hit, np.zeros((self.n_logs, extra), bool)])
            self.held = np.concatenate([self.held, np.full(extra, np.nan)])
        self.obstacle_hits += np.bincount(k, minlength=len(self.obstacle_names))
        self.log_hit[log[ob], k] = True
        self.log_log_hits += int((~ob).sum())

    def flush(self):
        """Flush the trajectory file, if one is written."""
        if self.inner is not None:
            self.inner.flush()

    def set_attrs(self, **attrs):
        """Global attributes of the trajectory file, if one is written."""
        if self.inner is not None:
            self.inner.set_attrs(**attrs)

    def close(self, finalize=True):
        """Close the trajectory file, if one is written; its path (or None)."""
        if self.inner is not None:
            self.path = self.inner.close(finalize=finalize)
        return self.path

    # ----------------------------------------------------------------- the result
    def summary(self, member=0, parameters=None, info=None) -> MemberSummary:
        """The member reduced: faces passed, first arrivals, fates, hits, held spans."""
        if self.occ_t is not None:
            self._close_record()
        e = self.entries
        n = e.compact()
        faces, face_logs, arrival = _per_face(e.keys, e.times, n, e.n_faces)
        idle = np.flatnonzero((self.status == STRANDED) | (self.status == RESTING))
        return MemberSummary(
            member=int(member), n_faces=e.n_faces, n_logs=self.n_logs, faces=faces,
            face_logs=face_logs, face_arrival=arrival,
            status_counts=np.bincount(self.status, minlength=5).astype(np.int64),
            idle_x=self.last_x[idle], idle_y=self.last_y[idle],
            idle_status=self.status[idle].copy(), idle_face=self.last_face[idle],
            obstacle_names=list(self.obstacle_names), obstacle_hits=self.obstacle_hits.copy(),
            obstacle_logs=self.log_hit.sum(axis=0).astype(np.int64),
            log_log_hits=self.log_log_hits, obstacle_held=self.held.copy(),
            parameters=dict(parameters or {}),
            info=dict(info or {}))


def unique_names(names) -> list:
    """Obstacle names as labels: unnamed or repeated ones get ``obstacle_<k>``."""
    out = []
    for k, name in enumerate(names):
        out.append(name if name and name not in out else f"obstacle_{k}")
    return out
