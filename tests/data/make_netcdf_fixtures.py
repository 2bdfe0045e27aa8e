"""Regenerate the hand-made NetCDF fixtures of tests/test_adapters_netcdf.py (no tool here writes
these formats, so they are written with netCDF4 following the real layouts).

ugrid/dflowfm_map.nc   a D-Flow FM map file: mesh2d_* names, 1-based face_node_connectivity with
                       _FillValue -999 (9 quads and 6 triangles on [0, 4] x [0, 3]),
                       mesh2d_node_z, mesh2d_flowelem_bl, mesh2d_s1, mesh2d_waterdepth,
                       mesh2d_ucx, mesh2d_ucy, time in 'seconds since 2001-01-01 00:00:00'
cf_grid/lisflood.nc    a LISFLOOD-FP-like raster: 6 x 4 cells of 10 m, north-up (y decreasing),
                       DEM, depth H, edge discharges Qx (nx + 1 edges) and Qy (ny + 1 edges) in
                       m3 s-1, time in hours

Fields are linear in x, y (and t), so that the tests know the exact values anywhere:
    UGRID  bed = -0.5 + 0.1 x;  level = 1 + 1e-4 t - 0.02 x + 0.01 y;  depth = level - bed
           u = 0.3 + 0.05 y + 1e-5 t;  v = -0.02 x
    grid   bed = 2 + 0.01 (x - 1000);  depth = 0.5 + 0.001 (x - 1000) + 0.1 t_hours
           qx = 0.2 + 0.002 (x - 1000);  qy = 0.01 (y - 1000)   (per unit width, m2/s)

    python tests/data/make_netcdf_fixtures.py
"""

import os

import netCDF4
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def ugrid_mesh():
    nx, ny = 4, 3
    X, Y = np.meshgrid(np.arange(nx + 1.0), np.arange(ny + 1.0))
    x, y = X.ravel(), Y.ravel()
    nid = np.arange(x.size).reshape(ny + 1, nx + 1)
    faces = []
    for j in range(ny):
        for i in range(nx):
            a, b, c, d = nid[j, i], nid[j, i + 1], nid[j + 1, i + 1], nid[j + 1, i]
            if i == nx - 1:  # the last column in triangles
                faces += [[a, b, c, -1], [a, c, d, -1]]
            else:
                faces.append([a, b, c, d])
    return x, y, np.array(faces)


def write_ugrid(path):
    x, y, fn = ugrid_mesh()
    n = (fn >= 0).sum(1)
    # the mean of the nodes is the centroid of a triangle or a rectangle
    fx = np.array([x[f[:k]].mean() for f, k in zip(fn, n, strict=True)])
    fy = np.array([y[f[:k]].mean() for f, k in zip(fn, n, strict=True)])
    quad = n == 4
    fx[~quad] = [x[f[:3]].mean() for f in fn[~quad]]
    times = np.array([0.0, 600.0, 1200.0])
    edges = set()
    for f, k in zip(fn, n, strict=True):
        for i in range(k):
            a, b = f[i], f[(i + 1) % k]
            edges.add((min(a, b), max(a, b)))
    edges = np.array(sorted(edges))
    with netCDF4.Dataset(path, "w", format="NETCDF4") as ds:
        ds.Conventions = "CF-1.8 UGRID-1.0 Deltares-0.10"
        ds.institution = "Deltares"
        ds.source = "D-Flow FM (hand-made fixture in its layout)"
        ds.createDimension("mesh2d_nNodes", x.size)
        ds.createDimension("mesh2d_nEdges", len(edges))
        ds.createDimension("mesh2d_nFaces", len(fn))
        ds.createDimension("mesh2d_nMax_face_nodes", 4)
        ds.createDimension("Two", 2)
        ds.createDimension("time", None)
        m = ds.createVariable("mesh2d", "i4")
        m.setncatts(dict(cf_role="mesh_topology", long_name="Topology data of 2D network",
                         topology_dimension=2, node_coordinates="mesh2d_node_x mesh2d_node_y",
                         node_dimension="mesh2d_nNodes", edge_node_connectivity="mesh2d_edge_nodes",
                         edge_dimension="mesh2d_nEdges",
                         max_face_nodes_dimension="mesh2d_nMax_face_nodes",
                         face_node_connectivity="mesh2d_face_nodes",
                         face_dimension="mesh2d_nFaces",
                         face_coordinates="mesh2d_face_x mesh2d_face_y"))
        px, py = "projection_x_coordinate", "projection_y_coordinate"
        for nm, arr, dim, std in (("mesh2d_node_x", x, "mesh2d_nNodes", px),
                                  ("mesh2d_node_y", y, "mesh2d_nNodes", py),
                                  ("mesh2d_face_x", fx, "mesh2d_nFaces", px),
                                  ("mesh2d_face_y", fy, "mesh2d_nFaces", py)):
            v = ds.createVariable(nm, "f8", (dim,))
            v.setncatts(dict(units="m", standard_name=std, mesh="mesh2d",
                             location="node" if "node" in nm else "face"))
            v[:] = arr
        v = ds.createVariable("mesh2d_node_z", "f8", ("mesh2d_nNodes",), fill_value=-999.0)
        v.setncatts(dict(mesh="mesh2d", location="node", coordinates="mesh2d_node_x mesh2d_node_y",
                         standard_name="altitude", long_name="z-coordinate of mesh nodes",
                         units="m", positive="up"))
        v[:] = -0.5 + 0.1 * x
        v = ds.createVariable("mesh2d_edge_nodes", "i4", ("mesh2d_nEdges", "Two"), fill_value=-999)
        v.setncatts(dict(cf_role="edge_node_connectivity", mesh="mesh2d", location="edge",
                         start_index=1))
        v[:] = edges + 1
        v = ds.createVariable("mesh2d_face_nodes", "i4",
                              ("mesh2d_nFaces", "mesh2d_nMax_face_nodes"), fill_value=-999)
        v.setncatts(dict(cf_role="face_node_connectivity", mesh="mesh2d", location="face",
                         long_name="Mapping from every face to its corner nodes "
                                   "(counterclockwise)", start_index=1))
        v[:] = np.where(fn >= 0, fn + 1, -999)
        v = ds.createVariable("mesh2d_flowelem_bl", "f8", ("mesh2d_nFaces",), fill_value=-999.0)
        v.setncatts(dict(mesh="mesh2d", location="face", coordinates="mesh2d_face_x mesh2d_face_y",
                         standard_name="altitude", long_name="Flow element center bedlevel (bl)",
                         units="m", positive="up"))
        bl = -0.5 + 0.1 * fx
        v[:] = bl
        t = ds.createVariable("time", "f8", ("time",))
        t.setncatts(dict(units="seconds since 2001-01-01 00:00:00", standard_name="time"))
        t[:] = times
        spec = {
            "mesh2d_s1": ("sea_surface_height", "Water level", "m"),
            "mesh2d_waterdepth": ("sea_floor_depth_below_sea_surface",
                                  "Water depth at pressure points", "m"),
            "mesh2d_ucx": ("sea_water_x_velocity", "Flow element center velocity vector, "
                                                   "x-component", "m s-1"),
            "mesh2d_ucy": ("sea_water_y_velocity", "Flow element center velocity vector, "
                                                   "y-component", "m s-1"),
        }
        for nm, (std, ln, units) in spec.items():
            v = ds.createVariable(nm, "f8", ("time", "mesh2d_nFaces"), fill_value=-999.0)
            v.setncatts(dict(mesh="mesh2d", location="face", coordinates="mesh2d_face_x "
                             "mesh2d_face_y", standard_name=std, long_name=ln, units=units))
        for k, tk in enumerate(times):
            s1 = 1.0 + 1e-4 * tk - 0.02 * fx + 0.01 * fy
            ds["mesh2d_s1"][k] = s1
            ds["mesh2d_waterdepth"][k] = s1 - bl
            ds["mesh2d_ucx"][k] = 0.3 + 0.05 * fy + 1e-5 * tk
            ds["mesh2d_ucy"][k] = -0.02 * fx


def write_lisflood(path):
    nx, ny, d = 6, 4, 10.0
    xc = 1000.0 + d / 2 + d * np.arange(nx)
    yc = (1000.0 + d / 2 + d * np.arange(ny))[::-1]  # north-up raster
    xe = 1000.0 + d * np.arange(nx + 1)
    ye = (1000.0 + d * np.arange(ny + 1))[::-1]
    th = np.array([0.0, 0.5, 1.0])
    with netCDF4.Dataset(path, "w", format="NETCDF4") as ds:
        ds.Conventions = "CF-1.8"
        ds.source = "LISFLOOD-FP (hand-made fixture in its layout)"
        for nm, n in (("x", nx), ("y", ny), ("x_edge", nx + 1), ("y_edge", ny + 1)):
            ds.createDimension(nm, n)
        ds.createDimension("time", None)
        for nm, arr, axis in (("x", xc, "X"), ("y", yc, "Y"), ("x_edge", xe, None),
                              ("y_edge", ye, None)):
            v = ds.createVariable(nm, "f8", (nm,))
            v.units = "m"
            if axis:
                v.axis = axis
                v.standard_name = f"projection_{nm}_coordinate"
            v[:] = arr
        t = ds.createVariable("time", "f8", ("time",))
        t.units = "hours since 2020-01-01 00:00:00"
        t.standard_name = "time"
        t[:] = th
        X, Y = np.meshgrid(xc - 1000, yc - 1000)
        dem = ds.createVariable("DEM", "f8", ("y", "x"), fill_value=-9999.0)
        dem.setncatts(dict(units="m", long_name="bed elevation", standard_name="altitude"))
        dem[:] = 2 + 0.01 * X
        h = ds.createVariable("H", "f8", ("time", "y", "x"), fill_value=-9999.0)
        h.setncatts(dict(units="m", long_name="water depth"))
        qx = ds.createVariable("Qx", "f8", ("time", "y", "x_edge"), fill_value=-9999.0)
        qx.setncatts(dict(units="m3 s-1", long_name="flow between cells in x, per edge"))
        qy = ds.createVariable("Qy", "f8", ("time", "y_edge", "x"), fill_value=-9999.0)
        qy.setncatts(dict(units="m3 s-1", long_name="flow between cells in y, per edge"))
        XE, YEx = np.meshgrid(xe - 1000, yc - 1000)
        XEy, YE = np.meshgrid(xc - 1000, ye - 1000)
        for k, tk in enumerate(th):
            h[k] = 0.5 + 0.001 * X + 0.1 * tk
            qx[k] = (0.2 + 0.002 * XE) * d
            qy[k] = (0.01 * YE) * d


if __name__ == "__main__":
    write_ugrid(os.path.join(HERE, "ugrid", "dflowfm_map.nc"))
    write_lisflood(os.path.join(HERE, "cf_grid", "lisflood.nc"))
    for sub in ("ugrid", "cf_grid"):
        for f in os.listdir(os.path.join(HERE, sub)):
            print(sub, f, os.path.getsize(os.path.join(HERE, sub, f)), "bytes")
