#!/usr/bin/env python3
"""The default run's work-precision diagram for a few rows, from Python.

PYTHONPATH=build/python python3 examples/work_precision.py [rows ...]
Runs each row at the default run's h or rtol list on the swinging sheet,
measures e_rms(t_end) against the CVODE reference (rtol 1e-10), prints the
equal-accuracy table and draws out/work_precision.png.
"""
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

import clothbench

scene = clothbench.load_scene("swinging_sheet")
rows = sys.argv[1:] or ["sbdf2", "sbdf3", "arkode/ark4", "cvode"]
ref = clothbench.reference(scene)["positions"][-1]
runs = []
for row in rows:
    key = clothbench.row_param(row)
    points = []
    for p in clothbench.default_params(scene, row):
        r = clothbench.run(scene, row, **{key: p})
        if r["status"] == "ok":
            points.append((r["solver_time_s"], clothbench.error_rms(r["positions"][-1], ref)))
    runs.append((row, points))
    plt.loglog([e for _, e in points], [t for t, _ in points], "o-", label=row)
table = clothbench.equal_accuracy(runs)
for label, costs, ratios, bounds in zip(table["labels"], table["cost"], table["ratio"], table["upper_bound"]):
    print(f"{label:14}" + "".join(f"{'≤' if b else '':>3}{c:6.3f} s ({q:.2f}x)" if c is not None and q is not None
                                  else f"{'-':>20}" for c, q, b in zip(costs, ratios, bounds)))
print("fastest:", table["fastest"])
plt.xlabel("e_rms(t_end) [m]"), plt.ylabel("solver time [s]"), plt.legend(), plt.gca().invert_xaxis()
os.makedirs("out", exist_ok=True)
plt.savefig("out/work_precision.png", dpi=120)
