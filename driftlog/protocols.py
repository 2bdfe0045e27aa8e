"""The contracts between the parts: what a flow field offers, what the contact model moves.

Two protocols (``typing.Protocol``, checked at run time by ``isinstance`` and by
tests/test_protocols.py on every shipped class):

- ``FlowFieldLike``: what the tracker, the physics chooser, the recorders and the readers'
  callers use of a flow field.  ``driftlog.flow.FlowField`` is the base class that provides
  ``sample`` (over ``sample_into``), the empty snapshot list of steady fields and
  ``mesh_kernel() -> None``; ``MeshFlowField`` (and the readers built on it) answer
  ``mesh_kernel()`` with the arrays the fused tracking kernels read (``flow.MeshKernel``), the
  explicit capability that replaces any guess from the class or its methods.
- ``ContactBodies``: what ``driftlog.contact.ContactModel`` reads and calls on the bodies it
  moves (``Tracker``, ``contact.BallisticLogs``): compact state arrays of the moving logs, the
  time, ``advance`` (free motion), ``save``/``restore`` (to retry a step), and
  ``invalidate_flow`` (positions were moved by the contact model: flow samples at the logs
  are stale).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:  # type names only: no import at run time
    from driftlog.flow import FlowSample, MeshKernel
    from driftlog.mesh import Mesh

__all__ = ["FlowFieldLike", "ContactBodies"]


@runtime_checkable
class FlowFieldLike(Protocol):
    """A flow field: depth, velocity and their derivatives at points and times.

    Attributes
    ----------
    name : str
        For messages and provenance.
    mesh : Mesh or None
        The mesh the field lives on (walls for contacts, ensemble maps), None for formulas.
    dry_depth : float
        Depth (m) below which a sample is dry.
    """

    name: str
    mesh: Mesh | None
    dry_depth: float

    @property
    def times(self) -> np.ndarray:
        """Snapshot times (s): the hydrodynamic steps sub-steps land on; empty when steady."""

    @property
    def time_span(self) -> tuple[float, float]:
        """(first, last) time covered (s); infinite for fields without an end."""

    def sample(self, x, y, t, face=None) -> FlowSample:
        """The flow at points (x, y) and time(s) t (``face``: location hints)."""

    def sample_into(self, x, y, t, face, out, flag) -> None:
        """Kernel entry: fill ``out`` (n, NVAR) and ``flag`` (n,), update the hints ``face``."""

    def mesh_kernel(self) -> MeshKernel | None:
        """The arrays of the fused mesh kernels when they reproduce ``sample_into``, else None."""


@runtime_checkable
class ContactBodies(Protocol):
    """The moving logs a contact model acts on (compact arrays over the moving logs only).

    Attributes
    ----------
    state : ndarray (n, NSTATE)
        x, y, theta, u, v, omega (``driftlog.columns``); the contact model changes velocities
        (impulses) and positions (overlap removal) in place.
    t : float
        Current time (s).
    ids, length, radius, mass, inertia : ndarray (n,)
        Log ids (stable across changes of the moving set) and properties.
    min_step : float
        Shortest step (s) the bodies accept; a contact step below it is a jam.

    Optional: ``max_step()``, the sub-step bound at the current state (event-driven contacts
    take it again after impulses change velocities); ``keeps_first_stage`` true when
    ``advance(dt, have_d0=True)`` reuses the first stage ``max_step`` computed at the same
    state (the tracker).
    """

    state: np.ndarray
    t: float
    ids: np.ndarray
    length: np.ndarray
    radius: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    min_step: float

    def advance(self, dt: float) -> None:
        """Free motion (flow forces, no contacts) over dt."""

    def save(self) -> object:
        """A copy of what ``advance`` changes, for ``restore``."""

    def restore(self, saved: object) -> None:
        """Back to a ``save()``."""

    def invalidate_flow(self) -> None:
        """Positions were moved from outside: what was sampled at the logs is stale."""
