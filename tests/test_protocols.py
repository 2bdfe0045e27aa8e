"""Every shipped flow field and body class meets its contract (driftlog/protocols.py)."""

import importlib
import inspect
import pkgutil

import numpy as np
import pytest

from driftlog.analytic import DriftingEddy, SolidBodyRotation, UniformFlow, on_mesh
from driftlog.contact import BallisticLogs, ContactModel
from driftlog.flow import FlowField, MeshFlowField, MeshKernel
from driftlog.logs import Logs
from driftlog.mesh import Mesh
from driftlog.protocols import ContactBodies, FlowFieldLike
from driftlog.tracker import Tracker


def members(proto):
    """Names a protocol requires: its annotated attributes and its public methods/properties."""
    names = set(proto.__annotations__)
    names |= {k for k, v in vars(proto).items()
              if not k.startswith("_") and (callable(v) or isinstance(v, property))}
    return sorted(names)


def shipped_modules():
    """Import every module of driftlog and its readers; optional back-ends may be absent."""
    import driftlog.adapters

    for pkg, prefix in ((driftlog, "driftlog."), (driftlog.adapters, "driftlog.adapters.")):
        for info in pkgutil.walk_packages(pkg.__path__, prefix):
            if info.name.endswith("__main__"):  # runs the command line
                continue
            try:
                importlib.import_module(info.name)
            except ImportError:  # an optional dependency (fcl, a reader's library) missing
                continue


def flow_classes():
    shipped_modules()
    seen, todo = [], [FlowField]
    while todo:
        cls = todo.pop()
        for sub in cls.__subclasses__():
            if sub.__module__.startswith("driftlog") and sub not in seen:
                seen.append(sub)
                todo.append(sub)
    return seen


def test_protocol_members_are_what_the_callers_use():
    assert members(FlowFieldLike) == ["dry_depth", "mesh", "mesh_kernel", "name", "sample",
                                      "sample_into", "time_span", "times"]
    assert members(ContactBodies) == ["advance", "ids", "inertia", "invalidate_flow", "length",
                                      "mass", "min_step", "radius", "restore", "save", "state",
                                      "t"]


@pytest.mark.parametrize("cls", flow_classes(), ids=lambda c: f"{c.__module__}.{c.__name__}")
def test_every_flow_field_class_meets_the_contract(cls):
    for name in members(FlowFieldLike):
        assert hasattr(cls, name), f"{cls.__name__} lacks {name}"
    if inspect.isabstract(cls) or cls.sample_into is FlowField.sample_into:
        return  # a base (AnalyticField): its subclasses provide the sampling
    # a fused mesh kernel stands for the field's own sampling: a class that samples otherwise
    # than MeshFlowField must say it has none
    if issubclass(cls, MeshFlowField) and cls.sample_into is not MeshFlowField.sample_into:
        assert cls.mesh_kernel is not MeshFlowField.mesh_kernel, (
            f"{cls.__name__} samples with its own sample_into but inherits "
            "MeshFlowField.mesh_kernel (the fused kernels would sample differently)")


def test_flow_field_instances_and_their_mesh_kernel():
    mesh = Mesh.regular_grid(6, 4, 1.0)
    fields = [UniformFlow(), SolidBodyRotation(), DriftingEddy(snapshot=5.0),
              on_mesh(UniformFlow(0.5, 0.1), mesh, times=[0.0, 10.0])]
    for f in fields:
        assert isinstance(f, FlowFieldLike)
    assert all(f.mesh_kernel() is None for f in fields[:3])
    k = fields[3].mesh_kernel()
    assert isinstance(k, MeshKernel) and k.recovered and k.dry_depth == fields[3].dry_depth
    assert k.locator is mesh.locator()
    # the kernel's node values are the field's own: sampling through them is sample_into
    vals, a, inv_dt = k.node_values(2.5)
    assert a == 0.25 and inv_dt == 0.1
    np.testing.assert_array_equal(vals, fields[3].node_values(2.5)[0])


def test_bodies_meet_the_contact_contract():
    logs = Logs([1.0, 3.0], [1.0, 1.0], length=0.5, radius=0.05)
    tracker = Tracker(UniformFlow(), logs, t_end=1.0, contact=ContactModel())
    ballistic = BallisticLogs(np.zeros((2, 6)), 0.5, 0.05)
    for bodies in (tracker, ballistic):
        assert isinstance(bodies, ContactBodies)
        for name in members(ContactBodies):
            assert hasattr(bodies, name), f"{type(bodies).__name__} lacks {name}"
    assert tracker.min_step == tracker.step_options.min_step
