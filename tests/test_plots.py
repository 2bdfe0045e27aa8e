import shutil
import subprocess

import numpy as np
import pytest

from driftlog.api import find_case, track
from driftlog.plots import animate, log_outlines, plot_trajectories


@pytest.fixture(scope="module")
def vortex_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("plots") / "traj.nc"
    res = track(find_case("vortex"), output=out,
                overrides={"time": {"end": 40.0, "output_interval": 2.0}})
    return res.path


def test_log_outlines_are_capsules_to_scale():
    o = log_outlines([1.0], [2.0], [np.pi / 2], 4.0, 0.5)[0]
    # axis along y: the outline spans L + 2 r along y and 2 r along x
    assert np.isclose(o[:, 1].max() - o[:, 1].min(), 5.0)
    assert np.isclose(o[:, 0].max() - o[:, 0].min(), 1.0)
    assert np.allclose(o.mean(axis=0), [1.0, 2.0], atol=1e-12)


def test_gif_has_one_frame_per_record_and_the_log_moves(vortex_run, tmp_path):
    from PIL import Image

    out = animate(vortex_run, tmp_path / "a.gif", max_frames=8)
    assert out.suffix == ".gif"
    im = Image.open(out)
    assert im.n_frames == 8
    frames = []
    for k in (0, 7):
        im.seek(k)
        frames.append(np.asarray(im.convert("RGB"), dtype=int))
    # the log (brown) is drawn, and it is elsewhere at the end than at the start
    brown = [np.all(np.abs(f - [139, 69, 19]) < 40, axis=-1) for f in frames]
    assert brown[0].sum() > 50 and brown[1].sum() > 50
    assert (brown[0] & brown[1]).sum() < 0.5 * brown[0].sum()


@pytest.mark.skipif(shutil.which("ffprobe") is None, reason="ffmpeg not installed")
def test_mp4_frame_count(vortex_run, tmp_path):
    out = animate(vortex_run, tmp_path / "a.mp4", max_frames=12)
    assert out.suffix == ".mp4"
    probe = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
                            "-show_entries", "stream=nb_read_frames", "-of", "csv=p=0",
                            str(out)], capture_output=True, text=True, check=True)
    assert int(probe.stdout.strip()) == 12


def test_figure_marks_releases_and_labels_axes(vortex_run, tmp_path):
    fig = plot_trajectories(vortex_run, background="speed")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
    assert "release" in [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("speed" in a.get_ylabel() for a in fig.axes[1:])  # the colour bar
    fig.savefig(tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 10_000
