"""Ensembles: many debris scenarios on one flow, run on Dask, reduced to maps and statistics.

    from driftlog.ensemble import load_ensemble, run_ensemble
    result = run_ensemble("cases/vortex/ensemble.toml", workers=2)
    ds = result.dataset()      # pass probability, first arrival, stranding, hits per obstacle

- ``spec``: the ``[ensemble]`` section, the parameters to vary and their sampling;
- ``summary``: one member reduced as it runs (faces passed, first arrivals, fates, hits);
- ``aggregate``: the running reduction over members, intervals, UGRID NetCDF output;
- ``runner``: members as Dask tasks (LocalCluster or a scheduler), durable and resumable;
- ``figures``: PNG maps and charts of the aggregate.
"""

from driftlog.ensemble.aggregate import (
    Aggregate,
    clopper_pearson_interval,
    mean_interval,
    wilson_interval,
)
from driftlog.ensemble.runner import EnsembleResult, open_member, run_ensemble, run_member
from driftlog.ensemble.spec import Ensemble, Parameter, load_ensemble
from driftlog.ensemble.summary import MemberRecorder, MemberSummary, summarize_trajectories

__all__ = ["Aggregate", "Ensemble", "EnsembleResult", "MemberRecorder", "MemberSummary",
           "Parameter", "clopper_pearson_interval", "load_ensemble", "mean_interval",
           "open_member", "run_ensemble", "run_member", "summarize_trajectories",
           "wilson_interval"]
