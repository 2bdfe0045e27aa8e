"""Readers of other models' flow outputs, each returning a driftlog ``FlowField``.

Imported as ``driftlog.adapters`` (the folder sits at the top of the repository, DESIGN.md).
"""

__all__: list[str] = []
