"""Shared helpers of the benchmark scripts: timing, machine facts, result tables."""

import csv
import os
import platform
import time
from pathlib import Path

import numpy as np

from driftlog.columns import UB

RESULTS = Path(__file__).resolve().parent / "results"


def best_time(fn, repeat=3, min_time=0.2):
    """Best wall time of ``fn()`` over ``repeat`` runs (each repeated to last ``min_time``)."""
    best = np.inf
    for _ in range(repeat):
        n = 0
        t0 = time.perf_counter()
        while True:
            fn()
            n += 1
            dt = time.perf_counter() - t0
            if dt >= min_time:
                break
        best = min(best, dt / n)
    return best


def machine():
    """A line describing where the numbers were measured."""
    load = os.getloadavg()
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
            f"Python {platform.python_version()}, load average {load[0]:.2f} at start")


def write_table(name, rows, columns, title, notes=""):
    """Write rows (list of dicts) as benchmarks/results/<name>.csv and .md; print the table."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    with open(RESULTS / f"{name}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        for r in rows:
            w.writerow({c: r.get(c, "") for c in columns})

    def fmt(v):
        if isinstance(v, float):
            if (abs(v) < 1e-2 or abs(v) >= 1e4) and v != 0:
                return f"{v:.3g}"
            return f"{v:.3f}".rstrip("0").rstrip(".")
        return str(v)

    lines = [f"### {title}", "", f"Measured on {machine()}.", ""]
    if notes:
        lines += [notes, ""]
    lines.append("| " + " | ".join(columns) + " |")
    lines.append("|" + "|".join("---" for _ in columns) + "|")
    for r in rows:
        lines.append("| " + " | ".join(fmt(r.get(c, "")) for c in columns) + " |")
    text = "\n".join(lines) + "\n"
    (RESULTS / f"{name}.md").write_text(text)
    print(text)
    return text


def malpasset_mesh():
    from driftlog.mesh import read_mesh

    here = Path(__file__).resolve().parents[1]
    for d in (here.parent / "shared" / "data" / "malpasset", here / "cases" / "malpasset" / "data"):
        if (d / "malpasset_mesh.nc").is_file():
            return read_mesh(d / "malpasset_mesh.nc")
    raise FileNotFoundError("Malpasset mesh not found")


def run_recording_first_log(tracker, t0=None, u0=None):
    """Run ``tracker``, recording the first floating log's u after every sub-step.

    Returns (times, velocities, error name or None); a run that diverges or whose step
    collapses (IntegrationError, StepTooSmallError) stops with what was recorded so far.
    """
    from driftlog.tracker import IntegrationError, StepTooSmallError

    ts = [] if t0 is None else [t0]
    us = [] if u0 is None else [u0]
    advance = tracker.advance

    def recording(dt, have_d0=False):
        advance(dt, have_d0)
        if tracker.state.shape[0]:
            ts.append(tracker.t)
            us.append(tracker.state[0, UB])

    tracker.advance = recording
    try:
        tracker.run()
    except (IntegrationError, StepTooSmallError) as exc:
        return np.array(ts), np.array(us), type(exc).__name__
    return np.array(ts), np.array(us), None
