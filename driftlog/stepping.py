"""Sub-step control of the tracker: the step bounds and the status of each log.

The bounds of docs/model.md eq. (44) (length, angle, drag relaxation) and the classification
of a log by the flow at its centre (left the domain, stranded, resting, floating; with
``physics.motion = "friction"`` a resting log moves when the flow overcomes bed friction,
docs/model.md 6.1), as numba kernels over the floating logs' arrays; the errors a sub-step
can end with.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from driftlog.columns import DRY, L_PAR, L_PERP, L_ROT, OMEGA, OUTSIDE, THETA, UB, VB, H
from driftlog.errors import DriftlogError
from driftlog.logs import FLOATING, LEFT, RESTING, STRANDED
from driftlog.physics import rest_drive, sample_row

__all__ = ["StepOptions", "StepTooSmallError", "IntegrationError", "step_bound", "classify"]


class StepTooSmallError(DriftlogError):
    """The sub-step fell below integrator.min_step."""


class IntegrationError(DriftlogError):
    """The integration diverged (non-finite state)."""


@dataclass
class StepOptions:
    """Sub-step control (docs/model.md eq. (44)).

    ``clock``: "global" (Algorithm 1: every floating log takes the smallest sub-step any
    needs) or "per_log" (each log its own sub-steps between synchronisation times,
    ``driftlog.clocks``; docs/model.md section 11.1).  ``land_on_snapshots``: sub-steps end
    at every snapshot time of the flow (the paper); False lets them run across (section 11).
    """

    length_fraction: float = 1.0
    angle_step: float = np.pi / 4
    drag_fraction: float = 0.5
    max_step: float | None = None
    min_step: float = 1e-9
    clock: str = "global"
    land_on_snapshots: bool = True

    @classmethod
    def from_scenario(cls, section):
        """From a validated [integrator] section."""
        return cls(section["length_fraction"], section["angle_step"], section["drag_fraction"],
                   section["max_step"], section["min_step"], section.get("clock", "global"),
                   section.get("land_on_snapshots", True))


@nb.njit(cache=True)
def step_bound(S, length, lin, lf, ang, drag_fraction, explicit):
    """Largest sub-step allowed by the paper's bounds (and the drag relaxation bound)."""
    dt = np.inf
    for i in range(S.shape[0]):
        sp = np.sqrt(S[i, UB] ** 2 + S[i, VB] ** 2)
        if sp > 0.0:
            dt = min(dt, lf * length[i] / sp)
        om = abs(S[i, OMEGA])
        if om > 0.0:
            dt = min(dt, ang / om)
        if explicit and drag_fraction > 0.0:
            lam = max(lin[i, L_PAR], max(lin[i, L_PERP], lin[i, L_ROT]))
            if lam > 0.0:
                dt = min(dt, drag_fraction / lam)
    return dt


@nb.njit(cache=True)
def classify(F, flag, float_depth, status, friction, S, P, opt):
    """New status from the flow at the logs: left the domain, stranded (dry), resting, floating.

    Below its flotation depth ``float_depth`` a wet log rests; with ``friction`` (initial
    motion on the bed, ``physics.motion = "friction"``) it moves (status floating: transported)
    when the flow's forces on it at rest overcome bed friction (``physics.rest_drive``,
    docs/model.md 6.1), from its state ``S`` and parameter rows ``P``.  Returns how many
    statuses changed.
    """
    changed = 0
    for i in range(F.shape[0]):
        if flag[i] == OUTSIDE:
            s = LEFT
        elif flag[i] == DRY:
            s = STRANDED
        elif F[i, H] < float_depth[i]:
            s = RESTING
            if friction:
                fx, fy, ff = rest_drive(S[i, THETA], sample_row(F, i), P[i], opt)
                f = np.sqrt(fx * fx + fy * fy)
                if f > 0.0 and f >= ff:
                    s = FLOATING
        else:
            s = FLOATING
        if s != status[i]:
            changed += 1
        status[i] = s
    return changed
