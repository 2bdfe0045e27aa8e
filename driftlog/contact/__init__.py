"""Contacts between logs, walls and bridge piers (docs/model.md section 13; issue 5).

One module each: ``geometry`` (exact 2D capsule narrow phase), ``broadphase`` (hashed uniform
grid), ``obstacles`` (piers, polygons, walls, 3D meshes cut by the logs' plane), ``impulses``
(event-driven impulses), ``toi`` (conservative advancement), ``moreau`` (time-stepping
contact for jams), ``native`` and ``fcl_backend`` (the two distance backends), ``model`` (the
``ContactModel`` the tracker calls), ``ballistic`` (force-free logs for tests and benchmarks).
"""

from driftlog.contact.ballistic import BallisticLogs, run_contacts
from driftlog.contact.model import ContactJamError, ContactModel, Contacts
from driftlog.contact.obstacles import Obstacles

__all__ = ["ContactModel", "ContactJamError", "Contacts", "Obstacles", "BallisticLogs",
           "run_contacts"]
