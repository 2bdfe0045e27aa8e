"""The Malpasset comparison shared by benchmarks/malpasset.py and malpasset_peers.py.

Every solver's per-face extremes (driftlog's and ANUGA's) go through
``malpasset_compare.extremes_points`` and ``headline``; here on a hand-made mesh, extremes and
observations whose statistics are worked out by hand.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from driftlog.mesh import Mesh

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"


@pytest.fixture(scope="module")
def compare():
    spec = importlib.util.spec_from_file_location("malpasset_compare",
                                                  BENCH / "malpasset_compare.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _obs(id_, kind, x, level, arrival):
    return {"id": id_, "kind": kind, "x": x, "y": 50.0, "max_level_m": level,
            "arrival_s": arrival}


# ten 100 m cells along x; the dam at x = 0, so that the chainage of a point is its x
DAM = ((0.0, 0.0), (0.0, 100.0))
OBS = [_obs("P1", "field", 150.0, 10.0, np.nan),      # face 1: computed 13 -> +3
       _obs("P2", "field", 250.0, 12.0, np.nan),      # face 2: computed 8 -> -4
       _obs("P3", "field", 350.0, 5.0, np.nan),       # face 3: 1 cm deep at most: dry
       _obs("G1", "scale_model", 450.0, 7.0, 100.0),  # face 4: +0.5 m, arrival +10 s
       _obs("A", "transformer", 650.0, np.nan, 300.0),  # face 6: arrival -20 s
       _obs("C", "transformer", 850.0, np.nan, 500.0)]  # face 8: never reached


def _extremes():
    mesh = Mesh.regular_grid(10, 1, 100.0)
    bed = np.zeros(10)
    max_level = np.array([20.0, 13.0, 8.0, 0.01, 7.5, 6.0, 5.0, 4.0, np.nan, np.nan])
    max_depth = max_level - bed
    max_depth[3] = 0.01
    max_depth[8:] = 0.0
    arrival = np.array([0.0, 20.0, 50.0, np.nan, 110.0, 200.0, 280.0, 400.0, np.nan, np.nan])
    return mesh, bed, max_level, max_depth, arrival


def test_headline_statistics_by_hand(compare):
    mesh, bed, max_level, max_depth, arrival = _extremes()
    rows, extra = compare.extremes_points(mesh, bed, max_level, max_depth, arrival, OBS, DAM,
                                          0.05, 600.0)
    assert [r["face"] for r in rows] == [1, 2, 3, 4, 6, 8]
    np.testing.assert_allclose([r["chainage_m"] for r in rows], [o["x"] for o in OBS])
    h = compare.headline(rows)
    # levels: +3, -4, +0.5 at the wet points; P3 dry
    assert h["level_n"] == 3
    assert h["level_rmse_m"] == pytest.approx(np.sqrt((9.0 + 16.0 + 0.25) / 3.0), rel=1e-12)
    assert h["level_mean_m"] == pytest.approx(-0.5 / 3.0, rel=1e-12)
    assert (h["worst_point"], h["worst_error_m"]) == ("P2", -4.0)
    assert h["dry"] == ["P3"]
    # arrivals: +10 (G1), -20 (A); C not reached
    assert h["arrival_n"] == 2
    assert h["arrival_rms_s"] == pytest.approx(np.sqrt(250.0), rel=1e-12)
    assert h["arrival_mean_s"] == pytest.approx(-5.0, rel=1e-12)
    assert h["not_reached"] == ["C"]


def test_observed_reach_keeps_the_same_points_for_every_run(compare):
    mesh, bed, max_level, max_depth, arrival = _extremes()
    rows, _ = compare.extremes_points(mesh, bed, max_level, max_depth, arrival, OBS, DAM,
                                      0.05, 600.0)
    # observed front: 450 m at 100 s, 650 m at 300 s -> 550 m at 200 s
    assert [r["id"] for r in compare.observed_reach(rows, 200.0)] == ["P1", "P2", "P3", "G1"]
    # a run that reached nothing is cut at the same points
    dry_rows, _ = compare.extremes_points(mesh, bed, np.full(10, np.nan), np.zeros(10),
                                          np.full(10, np.nan), OBS, DAM, 0.05, 600.0)
    assert [r["id"] for r in compare.observed_reach(dry_rows, 200.0)] == ["P1", "P2", "P3",
                                                                          "G1"]
    h = compare.headline(compare.observed_reach(dry_rows, 200.0))
    assert h["level_n"] == 0 and np.isnan(h["level_rmse_m"])
    assert h["dry"] == ["P1", "P2", "P3", "G1"] and h["not_reached"] == ["G1"]
    # past the last observed arrival every point is kept
    assert len(compare.observed_reach(rows, 4000.0)) == len(OBS)
