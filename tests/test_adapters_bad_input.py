"""Bad input every NetCDF reader shares: truncated NetCDF-3 files and negative depths (issue 12).

A NetCDF-3 file cut short opens without complaint and netCDF4 reads the missing bytes as fill
values or garbage (velocities of 0-2 m/s where the file holds 0.5 m/s everywhere); it must be
refused.  Negative depths: round-off (down to 1 mm) is clipped to 0, deeper is refused naming
the variable, the value and the snapshot.
"""

import shutil
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from driftlog.adapters import open_flow_source
from driftlog.adapters._netcdf import NEGATIVE_DEPTH_TOLERANCE, netcdf3_expected_size

from driftlog.cli import main
from driftlog.errors import FlowFileError

UGRID = Path(__file__).parent / "data" / "ugrid" / "dflowfm_map.nc"


def write_grid(path, fmt="NETCDF3_CLASSIC", depth=2.0, level=None, nt=6, n=12):
    """A CF grid: uniform 0.5 m/s flow, ``depth`` (or a water ``level`` over a flat bed)."""
    with netCDF4.Dataset(path, "w", format=fmt) as ds:
        ds.createDimension("time", None)
        ds.createDimension("y", n)
        ds.createDimension("x", n)
        for nm in ("x", "y"):
            v = ds.createVariable(nm, "f8", (nm,))
            v[:] = 10.0 * (np.arange(n) + 0.5)
            v.units, v.standard_name = "m", f"projection_{nm}_coordinate"
        t = ds.createVariable("time", "f8", ("time",))
        t.units = "seconds since 2000-01-01"
        b = ds.createVariable("bed", "f4", ("y", "x"))
        b.standard_name = "altitude"
        b[:] = 0.0
        first = ("depth", "water_depth") if level is None else ("wse", "sea_surface_height")
        for nm, std in (first, ("u", "sea_water_x_velocity"), ("v", "sea_water_y_velocity")):
            v = ds.createVariable(nm, "f4", ("time", "y", "x"))
            v.standard_name, v.units = std, "m" if nm in ("depth", "wse") else "m s-1"
        for k in range(nt):
            t[k] = 10.0 * k
            ds[first[0]][k] = depth if level is None else level
            ds["u"][k] = 0.5
            ds["v"][k] = 0.0
    return path


def truncate(src, dst, fraction):
    data = Path(src).read_bytes()
    Path(dst).write_bytes(data[:int(len(data) * fraction)])
    return dst


@pytest.mark.parametrize("fmt", ["NETCDF3_CLASSIC", "NETCDF3_64BIT_OFFSET",
                                 "NETCDF3_64BIT_DATA"])
def test_header_size_of_complete_files(tmp_path, fmt):
    """The size the header declares is the file's size (to the last record's padding)."""
    path = write_grid(tmp_path / "g.nc", fmt)
    size, records = netcdf3_expected_size(path)
    assert records == 6
    assert 0 <= path.stat().st_size - size <= 3
    field = open_flow_source("auto", path)
    np.testing.assert_allclose(field.snapshot(5)["u"], 0.5)


@pytest.mark.parametrize("fraction", [0.3, 0.6, 0.999])
def test_truncated_netcdf3_is_refused(tmp_path, capsys, fraction):
    full = write_grid(tmp_path / "full.nc")
    cut = truncate(full, tmp_path / "cut.nc", fraction)
    # what netCDF4 alone makes of it: it opens, and reads the lost bytes as something
    with netCDF4.Dataset(cut) as ds:
        assert ds["u"].shape == (6, 12, 12)
    assert main(["import", str(cut), "-o", str(tmp_path / "out.nc")]) == 2
    err = capsys.readouterr().err
    assert "cut.nc: truncated NetCDF file" in err
    assert f"{cut.stat().st_size} bytes" in err and "declares" in err
    assert "Traceback" not in err
    assert not (tmp_path / "out.nc").exists()
    with pytest.raises(FlowFileError, match="truncated NetCDF file"):
        open_flow_source("cf_grid", cut)
    with pytest.raises(FlowFileError, match="truncated NetCDF file"):
        open_flow_source("auto", cut)
    assert main(["info", str(cut)]) == 2
    assert "truncated NetCDF file" in capsys.readouterr().err


def test_truncated_netcdf4_is_refused(tmp_path, capsys):
    """HDF5 knows its own end: netCDF4 refuses the file, and the message says why."""
    full = write_grid(tmp_path / "full4.nc", fmt="NETCDF4", n=30)
    cut = truncate(full, tmp_path / "cut4.nc", 0.7)
    assert main(["import", str(cut), "-o", str(tmp_path / "out.nc")]) == 2
    err = capsys.readouterr().err
    assert "cut4.nc: a NetCDF-4 / HDF5 file that cannot be read: truncated or damaged" in err


def test_truncated_ugrid_netcdf3_is_refused(tmp_path):
    """The check is the NetCDF opener's: every reader (here UGRID) gets it."""
    src = tmp_path / "map3.nc"
    with netCDF4.Dataset(UGRID) as a, netCDF4.Dataset(src, "w", format="NETCDF3_64BIT_OFFSET") as b:
        for name, dim in a.dimensions.items():
            b.createDimension(name, None if dim.isunlimited() else len(dim))
        for name, var in a.variables.items():
            v = b.createVariable(name, var.dtype, var.dimensions)
            v.setncatts({k: var.getncattr(k) for k in var.ncattrs() if k != "_FillValue"})
            v[:] = var[:]
    field = open_flow_source("ugrid", src, fill="dry")  # the complete copy reads
    assert field.times.size > 1
    cut = truncate(src, tmp_path / "map3_cut.nc", 0.8)
    with pytest.raises(FlowFileError, match="map3_cut.nc: truncated NetCDF file"):
        open_flow_source("ugrid", cut, fill="dry")


def test_negative_depth_refused_naming_variable_value_and_snapshot(tmp_path, capsys):
    path = write_grid(tmp_path / "neg.nc", depth=-1.0)
    assert main(["import", str(path), "-o", str(tmp_path / "out.nc")]) == 2
    err = capsys.readouterr().err
    assert "neg.nc: negative water depth -1 m from 'depth' at snapshot 0 (t = 0 s)" in err
    assert "144 faces below -0.001 m" in err


def test_level_below_bed_refused(tmp_path):
    path = write_grid(tmp_path / "lvl.nc", level=-0.5)
    field = open_flow_source("cf_grid", path)
    with pytest.raises(FlowFileError, match=r"negative water depth -0.5 m from 'wse' - bed at "
                                            r"snapshot 2 \(t = 20 s\)"):
        field.snapshot(2)


def test_round_off_negative_depth_clipped_to_dry(tmp_path):
    """Depths down to -1 mm (a float32 level equal to the bed) are dry ground, no error."""
    assert NEGATIVE_DEPTH_TOLERANCE == 1e-3
    path = write_grid(tmp_path / "small.nc", depth=-0.9e-3)
    field = open_flow_source("cf_grid", path)
    snap = field.snapshot(0)
    assert np.all(snap["h"] == 0.0) and np.all(snap["u"] == 0.0)
    s = field.sample(np.array([55.0]), np.array([55.0]), 5.0)
    assert not s.wet[0] and s.u[0] == 0.0


def test_negative_depth_in_a_partly_dry_file_is_refused(tmp_path):
    """One cell at -1 m among wet ones: not silently dry."""
    path = write_grid(tmp_path / "one.nc", nt=3)
    with netCDF4.Dataset(path, "a") as ds:
        d = ds["depth"][1]
        d[4, 7] = -1.0
        ds["depth"][1] = d
    field = open_flow_source("cf_grid", path)
    field.snapshot(0)
    with pytest.raises(FlowFileError, match=r"-1 m from 'depth' at snapshot 1 \(t = 10 s\), "
                                            r"face 55 \(1 faces"):
        field.snapshot(1)
    shutil.rmtree(tmp_path, ignore_errors=True)
