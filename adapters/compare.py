"""Flows from different hydro sources side by side: what ``driftlog compare`` builds on.

``flow_differences(reference, other, x, y, t)`` samples two flows at the same points (the logs'
positions along a trajectory, say) and returns the differences a comparison reports: depth,
velocity (vector and speed), direction, and where one is wet and the other dry or outside.
The trajectory side of the comparison (distance between runs, arrival times, hits) belongs to
the tracker's outputs; this module only looks at flows.
"""

from __future__ import annotations

import numpy as np

from driftlog.columns import WET

__all__ = ["sample_flows", "flow_differences", "summarize_differences"]


def sample_flows(fields, x, y, t):
    """Sample each flow at the same points and time(s): dict name -> FlowSample."""
    out = {}
    for i, f in enumerate(fields):
        name = getattr(f, "name", None) or f"flow {i}"
        if name in out:
            name = f"{name} ({i})"
        out[name] = f.sample(x, y, t)
    return out


def flow_differences(reference, other, x, y, t):
    """Differences other - reference at points (x, y) and time(s) t.

    Returns a dict of arrays (one value per point): ``depth`` (m), ``velocity`` (n, 2)
    (m/s), ``speed`` (m/s), ``direction`` (rad, in (-pi, pi], where both move),
    ``wet_mismatch`` (bool: wet in one flow only); and the two samples.
    """
    a = reference.sample(x, y, t)
    b = other.sample(x, y, t)
    ua = np.column_stack([a.u, a.v])
    ub = np.column_stack([b.u, b.v])
    sa, sb = np.hypot(a.u, a.v), np.hypot(b.u, b.v)
    moving = (sa > 0) & (sb > 0)
    ang = np.where(moving, np.arctan2(b.v, b.u) - np.arctan2(a.v, a.u), np.nan)
    ang = (ang + np.pi) % (2 * np.pi) - np.pi
    return {"depth": b.h - a.h, "velocity": ub - ua, "speed": sb - sa, "direction": ang,
            "wet_mismatch": (a.flag == WET) != (b.flag == WET),
            "reference": a, "other": b}


def summarize_differences(diff) -> dict:
    """Scalar summary of ``flow_differences`` (RMS and max of each, over points wet in both)."""
    both = (diff["reference"].flag == WET) & (diff["other"].flag == WET)
    out = {"points": int(both.size), "wet_in_both": int(both.sum()),
           "wet_mismatch": int(diff["wet_mismatch"].sum())}
    for k in ("depth", "speed"):
        v = diff[k][both]
        out[f"{k}_rms"] = float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")
        out[f"{k}_max_abs"] = float(np.max(np.abs(v))) if v.size else float("nan")
    dv = np.linalg.norm(diff["velocity"][both], axis=1)
    out["velocity_rms"] = float(np.sqrt(np.mean(dv ** 2))) if dv.size else float("nan")
    return out
