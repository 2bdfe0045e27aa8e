"""Figures and animations of trajectory files: logs to scale over the flow.

``plot_trajectories`` draws the paths of the logs over the flow (speed or depth as background,
the mesh optionally), the logs to scale with their orientation at the last record, their
release points, and contact hits.  ``animate`` writes an MP4 (ffmpeg) or GIF of the logs
moving over the flow.  Both read everything from the trajectory file, rebuilding the flow from
the scenario stored in it when no flow is given.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from driftlog.logs import STATUS_MEANINGS
from driftlog.trajectory import open_trajectories, require_observations

__all__ = ["plot_trajectories", "animate", "flow_of_trajectories", "log_outlines"]


def _mpl():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def flow_of_trajectories(ds, path=None):
    """The flow a trajectory file was computed on, rebuilt from its stored scenario.

    A coupled run's is its own flow file (the ``coupled_flow`` attribute, or the file of that
    name beside the trajectories ``path`` when the run was made from another folder), not
    the scenario's uncoupled flow (which would be solved for nothing).
    """
    from driftlog.scenario import load_scenario
    from driftlog.sources import flow_from_scenario

    resolved = ds.attrs.get("scenario_resolved")
    if not resolved:
        return None
    import warnings

    from driftlog.errors import DriftlogError, DriftlogWarning

    try:
        scen = load_scenario(json.loads(resolved))
        coupled = ds.attrs.get("coupled_flow")
        if coupled or scen["coupling"]["enabled"]:
            from driftlog.errors import FlowFileError
            from driftlog.flowfile import open_flow

            here = [Path(coupled)] if coupled else []
            if path is not None and coupled:
                here.append(Path(path).parent / Path(coupled).name)
            for f in here:
                if f.is_file():
                    return open_flow(f, dry_depth=scen["flow"]["dry_depth"])
            raise FlowFileError(f"{coupled or 'the coupled flow file'}: not found (the coupled "
                                "run's flow)")
        return flow_from_scenario(scen)
    except (DriftlogError, OSError) as exc:  # the flow file may have moved: no background
        warnings.warn(f"drawn without the flow in the background: {exc}", DriftlogWarning,
                      stacklevel=2)
        return None


def log_outlines(x, y, theta, length, radius, n_cap=8):
    """Capsule outlines (n, 2 n_cap + 2, 2) of logs: segment of length L, radius r."""
    x, y, theta = np.atleast_1d(x), np.atleast_1d(y), np.atleast_1d(theta)
    length = np.broadcast_to(length, x.shape)
    radius = np.broadcast_to(radius, x.shape)
    a = np.linspace(-np.pi / 2, np.pi / 2, n_cap + 1)
    # cap around +L/2 then around -L/2, in the log's frame
    cx = np.concatenate([0.5 * length[:, None] + radius[:, None] * np.cos(a),
                         -0.5 * length[:, None] - radius[:, None] * np.cos(a)], axis=1)
    cy = np.concatenate([radius[:, None] * np.sin(a), -radius[:, None] * np.sin(a)], axis=1)
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    return np.stack([x[:, None] + c * cx - s * cy, y[:, None] + s * cx + c * cy], axis=-1)


def _background(ax, flow, t, kind, bounds, show_mesh=False):
    """Speed or depth under the logs: on the mesh faces, or sampled on a grid."""
    if flow is None or kind in (None, "none"):
        return None
    label = {"speed": "flow speed (m/s)", "depth": "water depth (m)"}[kind]
    mesh = getattr(flow, "mesh", None)
    if mesh is not None:
        from matplotlib.collections import PolyCollection

        fv = flow.face_values(t)
        val = np.hypot(fv["u"], fv["v"]) if kind == "speed" else fv["h"]
        if mesh.n_faces > 2_000_000:
            return None
        # (faces, corners, 2); triangles of a mixed mesh repeat their first node
        fn = np.where(mesh.face_nodes >= 0, mesh.face_nodes, mesh.face_nodes[:, :1])
        verts = np.stack([mesh.node_x[fn], mesh.node_y[fn]], axis=-1)
        wet = fv["h"] > flow.dry_depth
        val = np.ma.masked_where(~wet, val)
        pc = PolyCollection(verts, array=val, cmap="Blues" if kind == "depth" else "viridis",
                            edgecolors="0.6" if show_mesh else "face",
                            linewidths=0.2 if show_mesh else 0.0, zorder=0)
        ax.add_collection(pc)
        dry = PolyCollection(verts[~wet], facecolors="0.85",
                             edgecolors="face", linewidths=0.0, zorder=0)
        ax.add_collection(dry)
        walls = mesh.boundary_segments(["wall"])
        ax.plot(walls[:, [0, 2]].T, walls[:, [1, 3]].T, color="k", lw=0.8, zorder=1)
        _colorbar(ax, pc, label, bounds)
        return pc
    x0, y0, x1, y1 = bounds
    gx, gy = np.meshgrid(np.linspace(x0, x1, 200), np.linspace(y0, y1, 200))
    s = flow.sample(gx.ravel(), gy.ravel(), t)
    val = (np.hypot(s.u, s.v) if kind == "speed" else s.h).reshape(gx.shape)
    im = ax.imshow(val, origin="lower", extent=(x0, x1, y0, y1), cmap="viridis", zorder=0,
                   aspect="auto")
    _colorbar(ax, im, label, bounds)
    return im


def _figsize(width, w, h):
    """Figure size for a domain w x h drawn to scale, with room for labels and colour bar.

    The colour bar goes below the map when the domain is elongated (see ``_colorbar``).
    """
    ratio = h / max(w, 1e-9)
    if w > 2.5 * h:
        return width, min(10.0, max(2.6, 0.8 * width * ratio + 2.2))
    return width, min(width, max(3.0, 0.8 * width * ratio)) + 1.0


def _colorbar(ax, mappable, label, bounds):
    """A colour bar beside a squarish domain, below an elongated one (a channel, a beach)."""
    wide = (bounds[2] - bounds[0]) > 2.5 * (bounds[3] - bounds[1])
    ax.figure.colorbar(mappable, ax=ax, label=label, shrink=0.8 if not wide else 0.6,
                       orientation="horizontal" if wide else "vertical",
                       pad=0.28 if wide else 0.04, aspect=40 if wide else 20)


def _bounds(ds, flow, margin=0.05):
    mesh = getattr(flow, "mesh", None)
    if mesh is not None:
        x0, y0, x1, y1 = mesh.bounds
    else:
        x, y = ds["x"].values, ds["y"].values
        r = float(ds["length"].max())
        x0, x1, y0, y1 = x.min() - r, x.max() + r, y.min() - r, y.max() + r
    dx, dy = (x1 - x0) * margin, (y1 - y0) * margin
    return x0 - dx, y0 - dy, x1 + dx, y1 + dy


FIGURE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def plot_trajectories(path, flow=None, background="speed", show_mesh=False, out=None,
                      time=None, ax=None, title=None):
    """Figure of the trajectories in a file; saved to ``out`` (PNG) if given. Returns the figure."""
    plt = _mpl()
    ds = open_trajectories(path)
    require_observations(ds, path, "nothing to plot")
    t = ds["time"].values
    t0, t1 = (float(t.min()), float(t.max())) if t.size else (0.0, 0.0)
    t_show = t1 if time is None else float(time)
    tol = 1e-9 * max(t1 - t0, 1.0)
    if not t0 - tol <= t_show <= t1 + tol:  # the last records before it, titled with it
        from driftlog.errors import ArgumentError

        raise ArgumentError(f"{path}: time {time!r} s is outside the trajectories' records, "
                            f"{t0:g} to {t1:g} s")
    if out is not None:
        from driftlog.files import check_output

        check_output(out, "figure", inputs=[path], suffixes=FIGURE_SUFFIXES)
    if flow is None and background not in (None, "none"):
        flow = flow_of_trajectories(ds, path)
    bounds = _bounds(ds, flow)
    if ax is None:
        w, h = bounds[2] - bounds[0], bounds[3] - bounds[1]
        fig, ax = plt.subplots(figsize=_figsize(10, w, h))
    fig = ax.figure
    _background(ax, flow, t_show, background, bounds, show_mesh)
    ti = ds["trajectory_index"].values
    x, y = ds["x"].values, ds["y"].values
    cmap = plt.get_cmap("tab10")
    ntraj = ds.sizes["trajectory"]
    from matplotlib.collections import LineCollection, PolyCollection

    segs = [np.column_stack([x[ti == k], y[ti == k]]) for k in range(ntraj)]
    colors = [cmap(k % 10) for k in range(ntraj)]
    import matplotlib.patheffects as pe

    ax.add_collection(LineCollection(segs, colors=colors, linewidths=1.4, zorder=2,
                                     path_effects=[pe.withStroke(linewidth=2.6, foreground="w")]))
    starts = np.array([s[0] for s in segs if len(s)])
    if starts.size:
        ax.scatter(starts[:, 0], starts[:, 1], s=12, c="w", edgecolors="k", zorder=3,
                   label="release")
    # logs to scale at the shown time (their last record up to it)
    last = [np.flatnonzero((ti == k) & (t <= t_show + 1e-9)) for k in range(ntraj)]
    last = np.array([i[-1] for i in last if i.size])
    if last.size:
        k = ti[last]
        outl = log_outlines(x[last], y[last], ds["theta"].values[last],
                            ds["length"].values[k], ds["radius"].values[k])
        ax.add_collection(PolyCollection(outl, facecolors=[colors[j] for j in k],
                                         edgecolors="k", linewidths=0.6, zorder=4))
    if ds.sizes.get("hit", 0):
        hx, hy = ds["hit_x"].values, ds["hit_y"].values
        obst = ds["hit_other"].values < 0
        if obst.any():
            ax.scatter(hx[obst], hy[obst], marker="x", c="r", s=25, zorder=5,
                       label=f"obstacle hits ({obst.sum()})")
        if (~obst).any():
            ax.scatter(hx[~obst], hy[~obst], marker="+", c="m", s=25, zorder=5,
                       label=f"log-log contacts ({(~obst).sum()})")
    st = ds["status"].values
    names = STATUS_MEANINGS.split()
    final = [st[i[-1]] for i in (np.flatnonzero(ti == k) for k in range(ntraj)) if i.size]
    summary = ", ".join(f"{np.sum(np.array(final) == c)} {names[c]}"
                        for c in range(len(names)) if np.sum(np.array(final) == c))
    ax.set_xlim(bounds[0], bounds[2])
    ax.set_ylim(bounds[1], bounds[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    import textwrap

    ax.set_title(title or "\n".join(textwrap.wrap(
        f"{ds.attrs.get('title', '')}: t = {t_show:.4g} s ({summary})", 90)), fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    if out is not None:
        from driftlog.files import atomic_output

        with atomic_output(out) as tmp:  # complete or absent: never a truncated figure
            fig.savefig(tmp, dpi=130, bbox_inches="tight")
        plt.close(fig)
    return fig


def animate(path, out, flow=None, background="speed", fps=20, max_frames=300, dpi=100):
    """Animation of the logs over the flow: MP4 if ffmpeg is on the PATH, else GIF.

    The figure is drawn in full once; each frame then restores that picture and draws only the
    logs and the title on it (blitting), unless the flow is unsteady and its background changes.
    Frames go to ffmpeg as raw RGBA (or to Pillow for a GIF), without a PNG round trip.
    """
    plt = _mpl()
    from matplotlib.collections import PolyCollection

    ds = open_trajectories(path)
    require_observations(ds, path, "nothing to animate")
    from driftlog.errors import ArgumentError
    from driftlog.files import check_output

    if not (isinstance(fps, (int, float)) and fps > 0 and np.isfinite(fps)):
        raise ArgumentError(f"animate(fps={fps!r}): must be a number of frames per second > 0")
    check_output(out, "animation", inputs=[path], suffixes=(".mp4", ".gif"))
    if flow is None and background not in (None, "none"):
        flow = flow_of_trajectories(ds, path)
    out = Path(out)
    use_mp4 = shutil.which("ffmpeg") is not None and out.suffix.lower() != ".gif"
    if not use_mp4:
        out = out.with_suffix(".gif")
    t = ds["time"].values
    times = np.unique(t)
    if times.size > max_frames:
        times = times[np.linspace(0, times.size - 1, max_frames).round().astype(int)]
    bounds = _bounds(ds, flow)
    w, h = bounds[2] - bounds[0], bounds[3] - bounds[1]
    fig, ax = plt.subplots(figsize=_figsize(9, w, h), dpi=dpi)
    bg = _background(ax, flow, float(times[0]), background, bounds)
    unsteady = flow is not None and getattr(flow, "mesh", None) is not None and \
        len(getattr(flow, "times", ())) > 1 and bg is not None
    ti = ds["trajectory_index"].values
    L, R = ds["length"].values, ds["radius"].values
    x, y, th = ds["x"].values, ds["y"].values, ds["theta"].values
    from matplotlib.collections import LineCollection

    # the whole paths, faint, in the static picture: where each log is going
    ax.add_collection(LineCollection([np.column_stack([x[ti == k], y[ti == k]])
                                      for k in range(ds.sizes["trajectory"])],
                                     colors="w", alpha=0.5, linewidths=0.8, zorder=2))
    logs = PolyCollection([], facecolors="saddlebrown", edgecolors="k", linewidths=0.5, zorder=4,
                          animated=True)
    ax.add_collection(logs)
    ax.set_xlim(bounds[0], bounds[2])
    ax.set_ylim(bounds[1], bounds[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    title = ax.set_title(" ", animated=True)
    fig.tight_layout()
    canvas = fig.canvas
    canvas.draw()  # the layout is fixed from here on: the frames all have this size
    width, height = canvas.get_width_height()
    static = None if unsteady else canvas.copy_from_bbox(fig.bbox)
    sink = _FrameSink(out, width, height, fps, use_mp4)
    try:
        for tk in times:
            sel = np.flatnonzero(t == tk)
            logs.set_verts(log_outlines(x[sel], y[sel], th[sel], L[ti[sel]], R[ti[sel]]))
            title.set_text(f"t = {tk:.4g} s, {sel.size} logs")
            if static is None:
                fv = flow.face_values(float(tk))
                val = np.hypot(fv["u"], fv["v"]) if background == "speed" else fv["h"]
                bg.set_array(np.ma.masked_where(fv["h"] <= flow.dry_depth, val))
                canvas.draw()
            else:
                canvas.restore_region(static)
            ax.draw_artist(logs)
            ax.draw_artist(title)
            sink.write(np.asarray(canvas.buffer_rgba()))
    except BaseException:
        sink.abort()
        raise
    finally:
        plt.close(fig)
    sink.close()
    return out


class _FrameSink:
    """RGBA frames to an MP4 (an ffmpeg process reading raw video) or a GIF (Pillow)."""

    def __init__(self, out, width, height, fps, mp4):
        from driftlog.files import temporary_name

        # frames go to a temporary file, renamed when the animation is complete: an
        # interrupted animation leaves no truncated file under the final name
        self.final, self.fps, self.mp4 = Path(out), fps, mp4
        self.out = temporary_name(self.final)
        self.frames = []
        self.proc = None
        if mp4:
            import subprocess

            # yuv420p (what players expect) needs even sizes: pad by one pixel if odd
            cmd = [shutil.which("ffmpeg"), "-y", "-loglevel", "error", "-f", "rawvideo",
                   "-pix_fmt", "rgba", "-s", f"{width}x{height}", "-r", str(fps), "-i", "-",
                   "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2:color=white", "-vcodec", "libx264",
                   "-pix_fmt", "yuv420p", "-crf", "23", str(self.out)]
            self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)

    def write(self, rgba):
        if self.proc is not None:
            self.proc.stdin.write(rgba.tobytes())
        else:
            from PIL import Image

            self.frames.append(Image.fromarray(rgba[..., :3].copy()).quantize(colors=128))

    def abort(self):
        """Stop and remove the temporary file (an interrupted or failed animation)."""
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
        self.out.unlink(missing_ok=True)

    def close(self):
        """Finish the file and give it its final name."""
        import os

        try:
            if self.proc is not None:
                _, err = self.proc.communicate()
                if self.proc.returncode != 0:
                    from driftlog.errors import DriftlogError

                    raise DriftlogError(f"ffmpeg failed writing {self.final}: "
                                        f"{err.decode()[-500:]}")
            elif self.frames:
                self.frames[0].save(self.out, save_all=True, append_images=self.frames[1:],
                                    duration=int(1000 / self.fps), loop=0, format="GIF")
        except BaseException:
            self.abort()
            raise
        if self.out.exists():
            os.replace(self.out, self.final)
