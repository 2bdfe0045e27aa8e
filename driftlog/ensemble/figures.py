"""Figures of an ensemble's aggregated results (PNG), drawn from the aggregate file alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_ensemble"]

MAX_POLYGONS = 400_000  # above: faces drawn as points at their centroids


def _mesh_of(ds):
    """Face polygons (list of (k, 2) arrays) and centroids from the UGRID variables."""
    nx, ny = ds["mesh2d_node_x"].values, ds["mesh2d_node_y"].values
    fn = ds["mesh2d_face_nodes"].values
    fn = np.where(np.isfinite(fn), fn, -1).astype(np.int64)
    cx, cy = ds["mesh2d_face_x"].values, ds["mesh2d_face_y"].values
    if fn.shape[0] > MAX_POLYGONS:
        return None, cx, cy, fn, nx, ny
    verts = [np.column_stack([nx[f[f >= 0]], ny[f[f >= 0]]]) for f in fn]
    return verts, cx, cy, fn, nx, ny


def _map(ax, geom, values, label, cmap, title, vmin=None, vmax=None, under=None):
    from matplotlib.collections import PolyCollection

    verts, cx, cy, fn, nx, ny = geom
    ok = np.isfinite(values)
    if verts is not None:
        if under is not None:
            ax.add_collection(PolyCollection(verts, facecolors=under, edgecolors="face",
                                             linewidths=0.0, zorder=0))
        pc = PolyCollection([v for v, k in zip(verts, ok, strict=True) if k],
                            array=values[ok], cmap=cmap, edgecolors="face", linewidths=0.0,
                            zorder=1)
        pc.set_clim(vmin, vmax)
        ax.add_collection(pc)
    else:
        pc = ax.scatter(cx[ok], cy[ok], c=values[ok], s=1, cmap=cmap, vmin=vmin, vmax=vmax)
    ax.set_xlim(nx.min(), nx.max())
    ax.set_ylim(ny.min(), ny.max())
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.figure.colorbar(pc, ax=ax, label=label, shrink=0.8)


def _figure(plt, geom):
    _, _, _, _, nx, ny = geom
    w, h = nx.max() - nx.min(), ny.max() - ny.min()
    return plt.subplots(figsize=(10, max(3.0, min(10.0, 10 * h / max(w, 1e-9))) + 1))


def plot_ensemble(path, out_dir=None) -> list[Path]:
    """Maps of pass probability, first arrival and stranding, and hits per obstacle."""
    import xarray as xr

    from driftlog.plots import _mpl

    plt = _mpl()
    out_dir = Path(out_dir or Path(path).parent)
    ds = xr.open_dataset(path)
    geom = _mesh_of(ds)
    n = int(ds.attrs.get("members_done", 0))
    pct = f"{100 * float(ds.attrs.get('confidence', 0.95)):g}%"
    files = []

    fig, ax = _figure(plt, geom)
    p = ds["pass_probability"].values.astype(float)
    _map(ax, geom, np.where(p > 0, p, np.nan), "probability", "magma_r",
         f"probability that a log passes (fraction of {n} members)", 0.0, 1.0, under="0.92")
    files.append(out_dir / "pass_probability.png")
    fig.savefig(files[-1], dpi=120, bbox_inches="tight")
    plt.close(fig)

    fig, ax = _figure(plt, geom)
    _map(ax, geom, ds["first_arrival_earliest"].values, "time (s)", "viridis",
         f"earliest first arrival over {n} members", under="0.92")
    files.append(out_dir / "first_arrival.png")
    fig.savefig(files[-1], dpi=120, bbox_inches="tight")
    plt.close(fig)

    fig, ax = _figure(plt, geom)
    idle = (ds["stranded_logs"] + ds["resting_logs"]).values.astype(float)
    _map(ax, geom, np.where(idle > 0, idle, np.nan), "logs", "inferno_r",
         f"stranding locations: logs ending stranded or resting ({n} members)", under="0.92")
    files.append(out_dir / "stranding.png")
    fig.savefig(files[-1], dpi=120, bbox_inches="tight")
    plt.close(fig)

    if ds.sizes.get("obstacle", 0):
        names = [str(v) for v in ds["obstacle_name"].values]
        p = ds["hit_probability"].values
        lo, hi = ds["hit_probability_lower"].values, ds["hit_probability_upper"].values
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 0.5 * len(names) + 2.5))
        y = np.arange(len(names))
        a1.barh(y, p, xerr=[p - lo, hi - p], color="tab:red", alpha=0.8, capsize=3)
        a1.set_yticks(y, names)
        a1.set_xlim(0, 1)
        a1.set_xlabel(f"fraction of members with a hit ({pct} Wilson interval)")
        m = ds["hits_mean"].values
        mlo, mhi = ds["hits_mean_lower"].values, ds["hits_mean_upper"].values
        err = np.nan_to_num([m - mlo, mhi - m])
        a2.barh(y, m, xerr=err, color="tab:blue", alpha=0.8, capsize=3)
        a2.set_yticks(y, names)
        a2.set_xlabel(f"hits per member ({pct} Student-t interval)")
        fig.suptitle(f"hits per obstacle over {n} members")
        files.append(out_dir / "hits.png")
        fig.savefig(files[-1], dpi=120, bbox_inches="tight")
        plt.close(fig)
    ds.close()
    return files
