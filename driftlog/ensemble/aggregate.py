"""The running reduction of an ensemble, and its output: UGRID NetCDF on the flow mesh.

Members are added one at a time as they finish (``Aggregate.add``): counts per face, minima
and sums of first-arrival times, fates and hits per obstacle; memory is O(faces + members),
whatever the number of logs or records.  Counts are integers and minima exact, so they are
the same bit for bit whatever the order the members finish in; the sums behind means and
standard deviations agree to round-off.

Statistics (``confidence`` level c, default 0.95):

- probability that a log passes a face: the fraction of members in which at least one log
  passed it (``pass_probability``, with a Wilson score interval), and the fraction of all
  logs of all members (``log_pass_probability``);
- first arrival at a face (the earliest entry of any log of a member): the earliest over the
  members, and the mean and standard deviation over the members that reached it;
- hits per obstacle: the fraction of members with at least one hit, with Wilson and
  Clopper-Pearson intervals; the mean number of hits per member with a Student-t interval;
  the mean number of distinct logs that hit it;
- stranding: logs ending stranded (dry) or resting (too shallow to float), per face;
- clogging odds, per obstacle of ``[[obstacles]]`` and per ``group`` of them (a bridge's
  piers), the *sites*: the fraction of members in which the site is hit (a contact with any
  of its obstacles), and in which it is blocked (one of its obstacles held by a log for at
  least ``blocked_after`` seconds, as ``driftlog.ensemble.summary`` measures it), with Wilson
  score intervals (E. B. Wilson, "Probable inference, the law of succession, and statistical
  inference", J. Amer. Statist. Assoc. 22 (1927) 209-212).  Written as ``site_*`` variables
  of the aggregate file and as ``clogging.csv`` beside it (``clogging_table``).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from pathlib import Path

import numba as nb
import numpy as np

from driftlog._version import __version__
from driftlog.ensemble.summary import METHOD
from driftlog.logs import RESTING, STATUS_MEANINGS, STRANDED

__all__ = ["Aggregate", "wilson_interval", "clopper_pearson_interval", "mean_interval"]


# --------------------------------------------------------------------- intervals
def wilson_interval(k, n, confidence=0.95):
    """Wilson score interval of a binomial proportion k / n (arrays); NaN where n = 0."""
    from scipy import stats

    k, n = np.asarray(k, float), np.asarray(n, float)
    z = stats.norm.ppf(0.5 + confidence / 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = k / n
        den = 1 + z * z / n
        centre = (p + z * z / (2 * n)) / den
        half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    # the interval holds p exactly (at k = 0 or n, round-off would leave it a hair outside)
    return np.clip(np.fmin(centre - half, p), 0, 1), np.clip(np.fmax(centre + half, p), 0, 1)


def clopper_pearson_interval(k, n, confidence=0.95):
    """Clopper-Pearson ("exact") interval of a binomial proportion k / n; NaN where n = 0."""
    from scipy import stats

    k, n = np.asarray(k, float), np.asarray(n, float)
    a = 1 - confidence
    with np.errstate(invalid="ignore"):
        lo = np.where(k > 0, stats.beta.ppf(a / 2, k, n - k + 1), 0.0)
        hi = np.where(k < n, stats.beta.ppf(1 - a / 2, k + 1, n - k), 1.0)
    bad = n <= 0
    return np.where(bad, np.nan, lo), np.where(bad, np.nan, hi)


def mean_interval(total, total_sq, n, confidence=0.95):
    """Mean, and Student-t interval of the mean, from the sum and sum of squares of n values."""
    from scipy import stats

    total, total_sq, n = (np.asarray(a, float) for a in (total, total_sq, n))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / n
        var = np.maximum(total_sq - n * mean * mean, 0.0) / (n - 1)
        t = stats.t.ppf(0.5 + confidence / 2, np.maximum(n - 1, 1))
        half = np.where(n > 1, t * np.sqrt(var / n), np.nan)
    return mean, mean - half, mean + half


# --------------------------------------------------------------------- kernels
@nb.njit(cache=True)
def _add_faces(faces, face_logs, arrival, members, logs, first, arr_sum, arr_sq):
    for j in range(faces.size):
        f = faces[j]
        members[f] += 1
        logs[f] += face_logs[j]
        t = arrival[j]
        if t < first[f]:
            first[f] = t
        arr_sum[f] += t
        arr_sq[f] += t * t


@nb.njit(cache=True)
def _add_idle(idle_face, idle_status, stranded, resting):
    for j in range(idle_face.size):
        f = idle_face[j]
        if f < 0:
            continue
        if idle_status[j] == STRANDED:
            stranded[f] += 1
        elif idle_status[j] == RESTING:
            resting[f] += 1


# --------------------------------------------------------------------- the reduction
class Aggregate:
    """Running reduction over members (see the module docstring).

    Parameters
    ----------
    mesh : Mesh
        Faces of the maps (the flow mesh or the aggregation grid).
    members : int
        Number of members of the ensemble (the member table has one row per member).
    parameters : list of Parameter
        The varied parameters (for the member table).
    confidence : float
    blocked_after : float
        Held span (s) from which an obstacle counts as blocked in a member.
    run_span : float, optional
        The members' run (s, [time] start to end), when known: a ``blocked_after`` longer than
        it is said beside the clogging table (no obstacle could count as blocked).
    """

    def __init__(self, mesh, members, parameters=(), confidence=0.95, blocked_after=60.0,
                 run_span=None):
        nf = mesh.n_faces
        self.mesh = mesh
        self.n_members = int(members)
        self.parameters = list(parameters)
        self.confidence = float(confidence)
        self.blocked_after = float(blocked_after)
        self.run_span = None if run_span is None else float(run_span)
        self.geometry = None  # Obstacles of the base scenario (set_obstacles)
        self.members_passing = np.zeros(nf, np.int64)
        self.logs_passing = np.zeros(nf, np.int64)
        self.first_arrival = np.full(nf, np.inf)
        self.arrival_sum = np.zeros(nf)
        self.arrival_sumsq = np.zeros(nf)
        self.stranded_logs = np.zeros(nf, np.int64)
        self.resting_logs = np.zeros(nf, np.int64)
        self.status_counts = np.zeros(5, np.int64)
        self.total_logs = 0
        self.obstacle_names: list[str] = []
        self.members_hit = np.zeros(0, np.int64)
        self.hits = np.zeros(0, np.int64)
        self.hits_sq = np.zeros(0, np.int64)
        self.logs_hit = np.zeros(0, np.int64)
        self.log_log_hits = 0
        # the member table: one row per member
        n = self.n_members
        self.member_state = np.zeros(n, np.int8)  # 0 not run, 1 done, 2 failed
        self.member_logs = np.zeros(n, np.int64)
        self.member_status = np.zeros((n, 5), np.int64)
        self.member_wall = np.full(n, np.nan)
        self.member_cpu = np.full(n, np.nan)
        self.member_physics = np.full(n, "", dtype=object)
        self.member_hits: dict[int, np.ndarray] = {}
        self.member_held: dict[int, np.ndarray] = {}
        self.member_error: dict[int, str] = {}

    def set_obstacles(self, obstacles) -> None:
        """The ``[[obstacles]]`` geometry of the base scenario (an ``Obstacles``, or None).

        Its obstacles (named as the members name them) come first in the obstacle table, in
        scenario order; their groups make the clogging table's group rows, their capsules the
        map.
        """
        from driftlog.ensemble.summary import unique_names

        self.geometry = obstacles
        if obstacles is not None:
            self._obstacle_index(unique_names(obstacles.names))

    @property
    def done(self) -> int:
        """Members in the aggregate."""
        return int((self.member_state == 1).sum())

    @property
    def failed(self) -> int:
        """Members that failed (not in the statistics)."""
        return int((self.member_state == 2).sum())

    def _obstacle_index(self, names):
        idx = []
        for name in names:
            if name not in self.obstacle_names:
                self._grow_members(len(self.obstacle_names) + 1)
                self.obstacle_names.append(name)
                for a in ("members_hit", "hits", "hits_sq", "logs_hit"):
                    setattr(self, a, np.append(getattr(self, a), np.int64(0)))
            idx.append(self.obstacle_names.index(name))
        return np.array(idx, np.int64)

    def _grow_members(self, n):
        for tab, fill in ((self.member_hits, 0), (self.member_held, np.nan)):
            for i, a in tab.items():
                if a.size < n:
                    tab[i] = np.concatenate([a, np.full(n - a.size, fill, a.dtype)])

    def add(self, s) -> None:
        """Add one MemberSummary (a member counts once: adding it again is an error)."""
        if s.n_faces != self.mesh.n_faces:
            raise ValueError(f"member {s.member} was summarized on {s.n_faces} faces, the "
                             f"aggregate has {self.mesh.n_faces}")
        if self.member_state[s.member] == 1:
            raise ValueError(f"member {s.member} is already in the aggregate")
        _add_faces(s.faces, s.face_logs, s.face_arrival, self.members_passing,
                   self.logs_passing, self.first_arrival, self.arrival_sum, self.arrival_sumsq)
        _add_idle(s.idle_face, s.idle_status, self.stranded_logs, self.resting_logs)
        self.status_counts += s.status_counts
        self.total_logs += s.n_logs
        k = self._obstacle_index(s.obstacle_names)
        h = np.asarray(s.obstacle_hits, np.int64)
        self.members_hit[k] += h > 0
        self.hits[k] += h
        self.hits_sq[k] += h * h
        self.logs_hit[k] += s.obstacle_logs
        self.log_log_hits += int(s.log_log_hits)
        i = s.member
        self.member_state[i] = 1
        self.member_logs[i] = s.n_logs
        self.member_status[i] = s.status_counts
        self.member_wall[i] = s.info.get("wall_seconds", np.nan)
        self.member_cpu[i] = s.info.get("cpu_seconds", np.nan)
        self.member_physics[i] = s.info.get("physics_level", "")
        self.member_hits[i] = np.zeros(len(self.obstacle_names), np.int64)
        self.member_hits[i][k] = h
        self.member_held[i] = np.full(len(self.obstacle_names), np.nan)
        if s.obstacle_held is not None:
            self.member_held[i][k] = np.asarray(s.obstacle_held, float)
        self.member_error.pop(i, None)

    def fail(self, member: int, message: str) -> None:
        """Record a failed member (it stays out of the statistics)."""
        if self.member_state[member] != 1:
            self.member_state[member] = 2
            self.member_error[member] = message

    # ----------------------------------------------------------------- results
    def face_statistics(self) -> dict:
        """Per-face arrays (name -> (array, attrs))."""
        n = self.done
        c = self.confidence
        reached = self.members_passing > 0
        lo, hi = wilson_interval(self.members_passing, np.full(self.members_passing.shape, n), c)
        m = self.members_passing
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = self.arrival_sum / m
            var = np.maximum(self.arrival_sumsq - m * mean * mean, 0.0) / (m - 1)
        std = np.where(m > 1, np.sqrt(var), np.nan)
        first = np.where(reached, self.first_arrival, np.nan)
        tot = max(self.total_logs, 1)
        pct = f"{100 * c:g}%"
        return {
            "pass_probability": (self.members_passing / max(n, 1), dict(
                long_name="fraction of members in which at least one log passed the face",
                units="1")),
            "pass_probability_lower": (lo, dict(long_name=f"{pct} Wilson lower bound of "
                                                "pass_probability", units="1")),
            "pass_probability_upper": (hi, dict(long_name=f"{pct} Wilson upper bound of "
                                                "pass_probability", units="1")),
            "members_passing": (self.members_passing, dict(
                long_name="members in which at least one log passed the face")),
            "logs_passing": (self.logs_passing, dict(
                long_name="logs (over all members) that passed the face")),
            "log_pass_probability": (self.logs_passing / tot, dict(
                long_name="fraction of all logs of all members that passed the face",
                units="1")),
            "first_arrival_earliest": (first, dict(
                long_name="earliest first arrival of a log at the face over the members",
                units="s")),
            "first_arrival_mean": (np.where(reached, mean, np.nan), dict(
                long_name="mean first arrival over the members that reached the face",
                units="s")),
            "first_arrival_std": (std, dict(
                long_name="standard deviation of the first arrival over the members that "
                          "reached the face", units="s")),
            "stranded_logs": (self.stranded_logs, dict(
                long_name="logs (over all members) that ended stranded (dry) in the face")),
            "resting_logs": (self.resting_logs, dict(
                long_name="logs (over all members) that ended resting (too shallow to float) "
                          "in the face")),
            "stranding_probability": ((self.stranded_logs + self.resting_logs) / tot, dict(
                long_name="fraction of all logs that ended stranded or resting in the face",
                units="1")),
        }

    def obstacle_statistics(self) -> dict:
        """Per-obstacle arrays (name -> (array, attrs))."""
        n = self.done
        c = self.confidence
        pct = f"{100 * c:g}%"
        nn = np.full(self.members_hit.shape, n)
        wl, wh = wilson_interval(self.members_hit, nn, c)
        cl, ch = clopper_pearson_interval(self.members_hit, nn, c)
        mean, mlo, mhi = mean_interval(self.hits, self.hits_sq, nn, c)
        with np.errstate(invalid="ignore", divide="ignore"):
            p = self.members_hit / nn
            logs_mean = self.logs_hit / nn
        return {
            "hit_probability": (p, dict(long_name="fraction of members with at least one hit "
                                        "on the obstacle", units="1")),
            "hit_probability_lower": (wl, dict(long_name=f"{pct} Wilson lower bound")),
            "hit_probability_upper": (wh, dict(long_name=f"{pct} Wilson upper bound")),
            "hit_probability_cp_lower": (cl, dict(long_name=f"{pct} Clopper-Pearson lower "
                                                  "bound")),
            "hit_probability_cp_upper": (ch, dict(long_name=f"{pct} Clopper-Pearson upper "
                                                  "bound")),
            "members_hit": (self.members_hit, dict(long_name="members with at least one hit")),
            "hits_total": (self.hits, dict(long_name="hit events over all members")),
            "hits_mean": (mean, dict(long_name="mean hit events per member")),
            "hits_mean_lower": (mlo, dict(long_name=f"{pct} Student-t lower bound of "
                                          "hits_mean")),
            "hits_mean_upper": (mhi, dict(long_name=f"{pct} Student-t upper bound of "
                                          "hits_mean")),
            "logs_hitting_mean": (logs_mean, dict(long_name="mean number of distinct logs "
                                                  "hitting the obstacle per member")),
        }

    def _member_matrix(self, table, fill, dtype):
        n, m = self.n_members, len(self.obstacle_names)
        out = np.full((n, m), fill, dtype)
        for i, a in table.items():
            out[i, :a.size] = a
        return out

    def sites(self) -> list:
        """Clogging sites: (name, obstacle indices, kind), obstacles then groups of >= 2.

        Every obstacle of ``[[obstacles]]`` (walls and obstacles without geometry are left
        out: their held spans are not measured), then every ``group`` of two or more.
        """
        g = self.geometry
        if g is None:
            return []
        from driftlog.ensemble.summary import unique_names

        names = unique_names(g.names)
        idx = [self.obstacle_names.index(nm) for nm in names]
        out = [(nm, [k], "obstacle") for nm, k in zip(names, idx, strict=True)]
        groups = {}
        for grp, k in zip(g.groups, idx, strict=True):
            if grp:
                groups.setdefault(grp, []).append(k)
        out += [(grp, ks, "group") for grp, ks in groups.items() if len(ks) > 1]
        return out

    def clogging_table(self) -> dict:
        """Per site (``sites``): hit and blocked counts and probabilities, Wilson intervals.

        Over the members done; a site is hit in a member when any of its obstacles has a hit,
        blocked when any of them was held for at least ``blocked_after`` seconds.
        """
        done = self.member_state == 1
        n = int(done.sum())
        hits = self._member_matrix(self.member_hits, 0, np.int64)[done]
        held = self._member_matrix(self.member_held, np.nan, float)[done]
        rows = self.sites()
        mh = np.array([int((hits[:, ks].sum(axis=1) > 0).sum()) for _, ks, _ in rows], np.int64)
        with np.errstate(invalid="ignore"):
            blocked = held >= self.blocked_after
        mb = np.array([int(blocked[:, ks].any(axis=1).sum()) for _, ks, _ in rows], np.int64)
        longest = np.array([float(np.nanmax(held[:, ks])) if n and np.isfinite(held[:, ks]).any()
                            else np.nan for _, ks, _ in rows])
        nn = np.full(len(rows), n)
        hl, hh = wilson_interval(mh, nn, self.confidence)
        bl, bh = wilson_interval(mb, nn, self.confidence)
        with np.errstate(invalid="ignore", divide="ignore"):
            return dict(site=[r[0] for r in rows], kind=[r[2] for r in rows],
                        obstacles=[" ".join(self.obstacle_names[k] for k in r[1])
                                   for r in rows],
                        members=nn, members_hit=mh, hit_probability=mh / nn,
                        hit_lower=hl, hit_upper=hh, members_blocked=mb,
                        blocked_probability=mb / nn, blocked_lower=bl, blocked_upper=bh,
                        longest_held=longest)

    def write_clogging_csv(self, path) -> Path:
        """``clogging_table`` as CSV (one row per site), written atomically."""
        import csv

        t = self.clogging_table()
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(list(t))
            for j in range(len(t["site"])):
                w.writerow([_fmt(t[k][j]) for k in t])
        os.replace(tmp, path)
        return path

    def format_clogging(self) -> str:
        """``clogging_table`` as a text table (for the terminal)."""
        t = self.clogging_table()
        if not t["site"]:
            return ""
        pct = f"{100 * self.confidence:g}%"
        w = max(len(s) for s in t["site"] + ["site"])
        lines = [f"clogging odds over {t['members'][0]} members (blocked: held >= "
                 f"{self.blocked_after:g} s; {pct} Wilson intervals)",
                 f"  {'site':<{w}}  {'hit':>4}  {'P(hit)':<22}  {'blocked':>7}  "
                 f"{'P(blocked)':<22}  longest held (s)"]
        for j, name in enumerate(t["site"]):
            ph = _pci(t["hit_probability"][j], t["hit_lower"][j], t["hit_upper"][j])
            pb = _pci(t["blocked_probability"][j], t["blocked_lower"][j], t["blocked_upper"][j])
            lines.append(f"  {name:<{w}}  {t['members_hit'][j]:>4}  {ph:<22}  "
                         f"{t['members_blocked'][j]:>7}  {pb:<22}  {t['longest_held'][j]:.1f}")
        if self.run_span is not None and self.blocked_after > self.run_span:
            lines.append(f"  note: blocked_after = {self.blocked_after:g} s is longer than the "
                         f"run ({self.run_span:g} s): no obstacle can count as blocked; lower "
                         "[ensemble] blocked_after (--resume --set ensemble.blocked_after=... "
                         "recomputes the table without running the members again)")
        return "\n".join(lines)

    # ----------------------------------------------------------------- output
    def to_netcdf(self, path, attrs=None, parameter_values=None) -> Path:
        """Write the aggregate as UGRID-1.0 + CF NetCDF on the mesh (atomically).

        ``parameter_values``: {path: array (members,)} of numbers, or of indices into the
        parameter's list where its values are not numbers.
        """
        import netCDF4

        from driftlog.flowfile import FACE_DIM, _attrs_for_netcdf, write_mesh

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        with netCDF4.Dataset(tmp, "w", format="NETCDF4") as ds:
            ds.Conventions = "CF-1.11 UGRID-1.0"
            ds.title = "driftlog ensemble: aggregated results"
            ds.driftlog_version = __version__
            ds.history = (f"{_dt.datetime.now(_dt.UTC).isoformat(timespec='seconds')} "
                          f"driftlog {__version__}")
            ds.setncatts(_attrs_for_netcdf(dict(
                members=self.n_members, members_done=self.done, members_failed=self.failed,
                total_logs=self.total_logs, confidence=self.confidence,
                log_log_hits=self.log_log_hits, method=METHOD,
                **(attrs or {}))))
            write_mesh(ds, self.mesh)
            for name, (arr, a) in self.face_statistics().items():
                v = ds.createVariable(name, "f8" if arr.dtype.kind == "f" else "i8",
                                      (FACE_DIM,), zlib=True, complevel=1)
                v.setncatts(dict(a, mesh="mesh2d", location="face",
                                 coordinates="mesh2d_face_x mesh2d_face_y"))
                v[:] = arr
            ds.createDimension("obstacle", len(self.obstacle_names))
            on = ds.createVariable("obstacle_name", str, ("obstacle",))
            on.long_name = "obstacle ([[obstacles]] name)"
            for j, name in enumerate(self.obstacle_names):
                on[j] = name
            for name, (arr, a) in self.obstacle_statistics().items():
                v = ds.createVariable(name, "f8" if arr.dtype.kind == "f" else "i8",
                                      ("obstacle",))
                v.setncatts(a)
                v[:] = arr
            self._sites(ds)
            ds.createDimension("status", 5)
            st = ds.createVariable("status_logs", "i8", ("status",))
            st.setncatts(dict(long_name="final status of the logs over all members",
                              flag_values=np.arange(5, dtype=np.int8),
                              flag_meanings=STATUS_MEANINGS))
            st[:] = self.status_counts
            self._member_table(ds, parameter_values or {})
        os.replace(tmp, path)
        return path

    def _sites(self, ds):
        """Clogging table (``site`` dimension) and the obstacles' capsules (for the map)."""
        t = self.clogging_table()
        ds.createDimension("site", len(t["site"]))
        pct = f"{100 * self.confidence:g}%"
        for name, long_name in (("site", "clogging site: an obstacle or a group of them"),
                                ("kind", "obstacle or group"),
                                ("obstacles", "obstacles of the site (space separated)")):
            v = ds.createVariable(f"site_{name}" if name != "site" else "site_name", str,
                                  ("site",))
            v.long_name = long_name
            for j, val in enumerate(t[name]):
                v[j] = val
        attrs = dict(
            members_hit=dict(long_name="members in which a log hit the site"),
            hit_probability=dict(long_name="fraction of members in which a log hit the site",
                                 units="1"),
            hit_lower=dict(long_name=f"{pct} Wilson lower bound of site_hit_probability"),
            hit_upper=dict(long_name=f"{pct} Wilson upper bound of site_hit_probability"),
            members_blocked=dict(long_name="members in which the site was blocked"),
            blocked_probability=dict(
                long_name="fraction of members in which the site was blocked: one of its "
                          "obstacles occupied by a log (gap <= blocked_gap r) at every record "
                          "for at least blocked_after", units="1",
                blocked_after=self.blocked_after),
            blocked_lower=dict(long_name=f"{pct} Wilson lower bound of "
                                         "site_blocked_probability"),
            blocked_upper=dict(long_name=f"{pct} Wilson upper bound of "
                                         "site_blocked_probability"),
            longest_held=dict(long_name="longest span a log held the site over the members",
                              units="s"))
        for name, a in attrs.items():
            arr = np.asarray(t[name])
            v = ds.createVariable(f"site_{name}", "f8" if arr.dtype.kind == "f" else "i8",
                                  ("site",))
            v.setncatts(a)
            v[:] = arr
        g = self.geometry
        caps = g.capsules if g is not None else np.zeros((0, 5))
        ds.createDimension("capsule", len(caps))
        ds.createDimension("capsule_column", 5)
        v = ds.createVariable("obstacle_capsule", "f8", ("capsule", "capsule_column"))
        v.setncatts(dict(long_name="obstacles as capsules: segment ends ax, ay, bx, by and "
                                   "radius r", units="m"))
        v[:] = caps
        v = ds.createVariable("obstacle_capsule_owner", "i8", ("capsule",))
        v.long_name = "index of the capsule's obstacle (obstacle dimension)"
        if g is not None:
            from driftlog.ensemble.summary import unique_names

            idx = np.array([self.obstacle_names.index(nm) for nm in unique_names(g.names)],
                           np.int64)
            v[:] = idx[g.owner]

    def _member_table(self, ds, parameter_values):
        n = self.n_members
        ds.createDimension("member", n)
        v = ds.createVariable("member", "i8", ("member",))
        v.long_name = "member index"
        v[:] = np.arange(n)
        v = ds.createVariable("member_state", "i1", ("member",))
        v.setncatts(dict(long_name="state of the member", flag_values=np.arange(3, dtype=np.int8),
                         flag_meanings="not_run done failed"))
        v[:] = self.member_state
        v = ds.createVariable("member_logs", "i8", ("member",))
        v.long_name = "logs in the member"
        v[:] = self.member_logs
        v = ds.createVariable("member_status_logs", "i8", ("member", "status"))
        v.setncatts(dict(long_name="final status of the member's logs",
                         flag_meanings=STATUS_MEANINGS))
        v[:] = self.member_status
        v = ds.createVariable("member_hits", "i8", ("member", "obstacle"))
        v.long_name = "hit events of the member per obstacle"
        hits = np.zeros((n, len(self.obstacle_names)), np.int64)
        for i, h in self.member_hits.items():
            hits[i, :h.size] = h
        v[:] = hits
        v = ds.createVariable("member_held_seconds", "f8", ("member", "obstacle"))
        v.setncatts(dict(long_name="longest span a log held the obstacle in the member (NaN: "
                                   "not measured)", units="s"))
        v[:] = self._member_matrix(self.member_held, np.nan, float)
        v = ds.createVariable("member_wall_seconds", "f8", ("member",))
        v.setncatts(dict(long_name="wall time of the member's run", units="s"))
        v[:] = self.member_wall
        v = ds.createVariable("member_cpu_seconds", "f8", ("member",))
        v.setncatts(dict(long_name="CPU time of the member's run (its worker process)",
                         units="s"))
        v[:] = self.member_cpu
        v = ds.createVariable("member_physics_level", str, ("member",))
        v.long_name = "physics level the member ran with (auto resolved)"
        for i in np.flatnonzero(self.member_state == 1):
            v[i] = str(self.member_physics[i])
        v = ds.createVariable("member_error", str, ("member",))
        v.long_name = "why the member failed"
        for i, msg in self.member_error.items():
            v[i] = msg
        for p in self.parameters:
            vals = np.asarray(parameter_values.get(p.path, np.full(n, np.nan)))
            numeric = p.numeric and p.key != "place"
            v = ds.createVariable(f"parameter_{p.name}", "f8" if numeric else "i8", ("member",))
            a = dict(long_name=f"{p.path}: {p.kind} {json.dumps(p.args)}", scenario_key=p.path)
            if not numeric:
                a.update(long_name=f"{p.path}: index into the values", values=json.dumps(p.args))
            v.setncatts(a)
            v[:] = vals


def _fmt(v):
    if isinstance(v, float | np.floating):
        return f"{v:.6g}"
    return str(v)


def _pci(p, lo, hi):
    if not np.isfinite(p):
        return "-"
    return f"{p:.3f} [{lo:.3f}, {hi:.3f}]"
