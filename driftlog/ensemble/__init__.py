"""Ensembles: many debris scenarios on one flow, run on Dask, reduced to maps and statistics.

    from driftlog.ensemble import load_ensemble, run_ensemble
    result = run_ensemble("cases/vortex/ensemble.toml", workers=2)
    ds = result.dataset()      # pass probability, first arrival, stranding, hits per obstacle

- ``vary``: the ``[ensemble]`` section, the parameters to vary and their distributions;
- ``spec``: the ensemble file, its sampling and its members (plain scenarios);
- ``summary``: one member reduced as it runs (faces passed, first arrivals, fates, hits);
- ``aggregate``: the running reduction over members, intervals, UGRID NetCDF output;
- ``runner``: members as Dask tasks (LocalCluster or a scheduler), durable and resumable;
- ``figures``: PNG maps and charts of the aggregate.
"""

from __future__ import annotations

__all__ = ["Aggregate", "Ensemble", "EnsembleResult", "MemberRecorder", "MemberSummary",
           "Parameter", "clopper_pearson_interval", "load_ensemble", "mean_interval",
           "open_member", "run_ensemble", "run_member", "summarize_trajectories",
           "wilson_interval"]

_AGGREGATE = ("Aggregate", "clopper_pearson_interval", "mean_interval", "wilson_interval")
_RUNNER = ("EnsembleResult", "open_member", "run_ensemble", "run_member",
           "summarize_trajectories")
_SPEC = ("Ensemble", "Parameter", "load_ensemble")
_SUMMARY = ("MemberRecorder", "MemberSummary")


def __getattr__(name):
    """Import the submodule that holds ``name`` when it is first used.

    ``driftlog.scenario`` imports ``driftlog.ensemble.vary`` without the Dask runner.
    """
    if name in _AGGREGATE:
        from driftlog.ensemble import aggregate as mod
    elif name in _RUNNER:
        from driftlog.ensemble import runner as mod
    elif name in _SPEC:
        from driftlog.ensemble import spec as mod
    elif name in _SUMMARY:
        from driftlog.ensemble import summary as mod
    else:
        raise AttributeError(f"module 'driftlog.ensemble' has no attribute {name!r}")
    return getattr(mod, name)
