"""Regenerate the ANUGA .sww fixtures of tests/test_adapters_netcdf.py (needs `pip install anuga`,
the `bench` extra; the tests themselves read the committed files and do not need anuga).

A 4 m x 1 m channel (rectangular_cross mesh, 64 triangles) at UTM offset (xllcorner, yllcorner) =
(500000, 4000000): bed sloping down in x, 0.2 m of water, a Dirichlet stage of 0.3 m at the left,
run 4 s with a snapshot each second.
  channel_centroids.sww   centroid and vertex values (set_store_centroids(True)), smooth vertices
  channel_vertices.sww    vertex values only, stored uniquely per triangle (no smoothing)
  *.json                  ANUGA's own numbers: water volume at each time, centroid values and
                          coordinates (absolute) at the last time

    python tests/data/anuga/make_fixtures.py
"""

import json
import os
import shutil
import tempfile

import anuga

HERE = os.path.dirname(os.path.abspath(__file__))
XLL, YLL = 500000.0, 4000000.0


def run(name, centroids, unique):
    work = tempfile.mkdtemp()
    cwd = os.getcwd()
    os.chdir(work)
    try:
        points, vertices, boundary = anuga.rectangular_cross(8, 2, len1=4.0, len2=1.0)
        geo = anuga.Geo_reference(zone=31, xllcorner=XLL, yllcorner=YLL)
        domain = anuga.Domain(points, vertices, boundary, geo_reference=geo)
        domain.set_name(name)
        domain.set_datadir(work)
        domain.set_flow_algorithm("DE0")
        domain.set_minimum_storable_height(0.0)
        domain.set_store_centroids(centroids)
        if unique:
            domain.set_store_vertices_uniquely(True)
        domain.set_quantity("elevation", lambda x, y: -0.05 * x)
        domain.set_quantity("stage", expression="elevation + 0.2")
        domain.set_quantity("friction", 0.01)
        br = anuga.Reflective_boundary(domain)
        bd = anuga.Dirichlet_boundary([0.3 - 0.0, 0.0, 0.0])
        bo = anuga.Transmissive_boundary(domain)
        domain.set_boundary({"left": bd, "right": bo, "top": br, "bottom": br})
        ref = {"time": [], "water_volume": []}
        for t in domain.evolve(yieldstep=1.0, finaltime=4.0):
            ref["time"].append(float(t))
            ref["water_volume"].append(float(domain.get_water_volume()))
        # what ANUGA itself says at the last time, to check the adapter against
        cx, cy = domain.centroid_coordinates.T
        ref["centroid_x"] = (cx + XLL).tolist()
        ref["centroid_y"] = (cy + YLL).tolist()
        for q in ("stage", "elevation", "xmomentum", "ymomentum"):
            ref[q] = domain.get_quantity(q).centroid_values.tolist()
        ref["area"] = domain.areas.tolist()
        shutil.copy(os.path.join(work, name + ".sww"), os.path.join(HERE, name + ".sww"))
        with open(os.path.join(HERE, name + ".json"), "w") as f:
            json.dump(ref, f)
    finally:
        os.chdir(cwd)
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    run("channel_centroids", centroids=True, unique=False)
    run("channel_vertices", centroids=False, unique=True)
    for f in sorted(os.listdir(HERE)):
        if f.endswith(".sww"):
            print(f, os.path.getsize(os.path.join(HERE, f)), "bytes")
