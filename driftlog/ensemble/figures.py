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
        a1.barh(y, p, xerr=np.maximum([p - lo, hi - p], 0.0), color="tab:red", alpha=0.8, capsize=3)
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
    if ds.sizes.get("site", 0) and ds.sizes.get("capsule", 0):
        files.append(_clogging_map(plt, ds, geom, n, pct, out_dir / "clogging.png"))
    ds.close()
    return files


def _clogging_map(plt, ds, geom, n, pct, path):
    """The obstacles over the flow mesh, coloured by the probability that they are blocked."""
    from matplotlib import cm, colors
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Circle, Polygon

    verts, cx, cy, fn, nx, ny = geom
    fig, ax = _figure(plt, geom)
    if verts is not None:
        ax.add_collection(PolyCollection(verts, facecolors="0.93", edgecolors="0.8",
                                         linewidths=0.2, zorder=0))
    else:
        ax.scatter(cx, cy, s=0.2, c="0.85")
    p = ds["pass_probability"].values.astype(float)
    if verts is not None and np.any(p > 0):  # where the logs went, faint
        ok = p > 0
        pc = PolyCollection([v for v, k in zip(verts, ok, strict=True) if k],
                            array=p[ok], cmap="Blues", edgecolors="face", linewidths=0.0,
                            alpha=0.35, zorder=0.5)
        pc.set_clim(0, 1)
        ax.add_collection(pc)
    names = [str(v) for v in ds["obstacle_name"].values]
    site = [str(v) for v in ds["site_name"].values]
    kind = [str(v) for v in ds["site_kind"].values]
    pb = ds["site_blocked_probability"].values
    lo, hi = ds["site_blocked_lower"].values, ds["site_blocked_upper"].values
    cmap, norm = plt.get_cmap("YlOrRd"), colors.Normalize(0, 1)
    caps = ds["obstacle_capsule"].values
    owner = ds["obstacle_capsule_owner"].values
    prob = {s: j for j, s in enumerate(site) if kind[j] == "obstacle"}
    for k in np.unique(owner):
        j = prob.get(names[k])
        col = cmap(norm(pb[j])) if j is not None else "0.5"
        c = caps[owner == k]
        for ax_, ay, bx, by, r in c:
            if r > 0 and ax_ == bx and ay == by:
                ax.add_patch(Circle((ax_, ay), r, facecolor=col, edgecolor="k", lw=0.8,
                                    zorder=3))
            elif r > 0:
                d = np.array([bx - ax_, by - ay]) / np.hypot(bx - ax_, by - ay) * r
                q = np.array([[ax_, ay], [bx, by], [bx, by], [ax_, ay]])
                q += np.array([[-d[1], d[0]], [-d[1], d[0]], [d[1], -d[0]], [d[1], -d[0]]])
                ax.add_patch(Polygon(q, facecolor=col, edgecolor="k", lw=0.8, zorder=3))
            else:
                ax.plot([ax_, bx], [ay, by], color=col, lw=3, zorder=3)
        if j is not None:
            x, y = c[:, [0, 2]].max() + c[:, 4].max(), c[:, [1, 3]].mean()
            ax.annotate(f"{names[k]} {pb[j]:.2f} [{lo[j]:.2f}, {hi[j]:.2f}]", (x, y),
                        xytext=(4, 0), textcoords="offset points", ha="left", va="center",
                        fontsize=7, zorder=4,
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.7))
    groups = [f"{s} ({', '.join(str(ds['site_obstacles'].values[j]).split())}): {pb[j]:.2f} "
              f"[{lo[j]:.2f}, {hi[j]:.2f}]" for j, s in enumerate(site) if kind[j] == "group"]
    if groups:  # below the map: a group's obstacles may be far apart
        ax.annotate("groups: " + ";  ".join(groups), (0.0, 0.0), xycoords="axes fraction",
                    xytext=(0, -42), textcoords="offset points", ha="left", va="top",
                    fontsize=8)
    ax.set_xlim(nx.min(), nx.max())
    ax.set_ylim(ny.min(), ny.max())
    ax.set_aspect("equal")
    after = float(ds["site_blocked_probability"].attrs.get("blocked_after", np.nan))
    ax.set_title(f"probability that an obstacle is blocked (held >= {after:g} s), {n} members"
                 f"\nlabels: probability [{pct} Wilson score interval]")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.8,
                 label="probability of blocking")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path
