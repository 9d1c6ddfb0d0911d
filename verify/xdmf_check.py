#!/usr/bin/python3
"""Reads a result file's XDMF with meshio (an independent XDMF reader) and
checks it against the HDF5 file read with h5py: per trajectory (the reference
and every run with frames), the number of points, the quad cells, the number
of time steps and their times, the first frame's points and the last
frame's velocities.

    xdmf_check.py RESULT.h5

meshio's TimeSeriesReader reads one temporal collection per file, so each
collection is copied unchanged into its own XDMF beside the result file
(paths in an XDMF are relative to it) and read from there. Exit 0 if every
check passes, 1 with one line per failure otherwise."""
import copy
import os
import sys
import xml.etree.ElementTree as ET

try:
    import h5py
    import meshio
    import numpy as np
except ImportError as e:  # a failed check, not a skip
    sys.exit(f"xdmf_check: {e}; scripts/setup installs python3-meshio and python3-h5py")


def main(path):
    xdmf = os.path.splitext(path)[0] + ".xdmf"
    h5 = h5py.File(path, "r")
    tree = ET.parse(xdmf)
    domain = tree.getroot()[0]
    names = [g.get("Name") for g in domain if g.get("CollectionType") == "Temporal"]
    groups = (["reference"] if "reference" in h5 else []) + list(h5["runs"])
    with_frames = [g for g in groups
                   if any(k in h5[g if g == "reference" else "runs/" + g] for k in ("positions", "positions_ends"))]
    failures = []
    if names != with_frames:
        failures.append(f"collections {names} != trajectories with frames {with_frames}")
    faces = h5["scene/faces"][()]
    n = int(h5["scene"].attrs["n_particles"])
    one = os.path.join(os.path.dirname(os.path.abspath(path)), ".xdmf_check_one.xdmf")
    try:
        for name in names:
            g = h5[name if name == "reference" else "runs/" + name]
            t = copy.deepcopy(tree)
            d = t.getroot()[0]
            for grid in list(d):
                if grid.get("Name") != name:
                    d.remove(grid)
            t.write(one)
            with meshio.xdmf.TimeSeriesReader(one) as r:
                points, cells = r.read_points_cells()
                steps = [r.read_data(k) for k in range(r.num_steps)]
            if "positions" in g:
                frames, times = g["positions"], g["times"][()][: g["positions"].shape[0]]
            else:
                frames, times = g["positions_ends"], g["times"][()][[0, -1]]
            vel = g["velocities"] if "velocities" in g else g["velocities_ends"]
            checks = [
                (points.shape == (n, 3), f"points {points.shape} != ({n}, 3)"),
                (np.array_equal(points, frames[0]), "points != positions[0]"),
                (len(cells) == 1 and cells[0].type == "quad", f"cells {[c.type for c in cells]} != one quad block"),
                (len(cells) == 1 and np.array_equal(cells[0].data, faces), "quads != /scene/faces"),
                (len(steps) == frames.shape[0], f"{len(steps)} time steps != {frames.shape[0]} stored frames"),
                (np.array_equal([s[0] for s in steps], times), "step times != stored frame times"),
                ("velocity" in steps[-1][1] and np.array_equal(steps[-1][1]["velocity"], vel[-1]),
                 "last step's velocity != last stored velocities"),
            ]
            failures += [f"{name}: {msg}" for ok, msg in checks if not ok]
    finally:
        if os.path.exists(one):
            os.remove(one)
    for f in failures:
        print(f"xdmf_check: {path}: {f}")
    print(f"xdmf_check: {path}: {len(names)} temporal collections read by meshio {meshio.__version__}, "
          f"{len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
