#!/usr/bin/python3
"""Checks the equal-accuracy table of a result file against its runs (h5py):
for every method and target of /work_precision, no ok run of that method is
both cheaper than the reported solver time and at or below the target's
error; a method with a run at or below a target reports a time there (a
number, or an upper bound flagged in upper_bound), and one without reports
none.

    envelope_check.py RESULT.h5

Exit 0 if every check passes, 1 with one line per failure otherwise."""
import sys

import h5py


def main(path):
    failures = []
    with h5py.File(path, "r") as f:
        wp = f["work_precision"]
        labels = wp.attrs["labels"]
        labels = (labels.decode() if isinstance(labels, bytes) else labels).split(",")
        metric = wp.attrs.get("error_metric", b"final")
        key = f"error_{metric.decode() if isinstance(metric, bytes) else metric}_m"
        targets = wp["targets"][:]
        cost, bound = wp["solver_time"][:], wp["upper_bound"][:]
        runs = {}
        for rid, g in f["runs"].items():
            label = g.attrs["label"]
            label = label.decode() if isinstance(label, bytes) else label
            status = g.attrs["status"]
            if (status.decode() if isinstance(status, bytes) else status) == "ok" and key in g.attrs:
                runs.setdefault(label, []).append((float(g.attrs["solver_time_s"]), float(g.attrs[key])))
        checked = 0
        for m, label in enumerate(labels):
            points = runs.get(label, [])
            for j, target in enumerate(targets):
                reachable = [c for c, e in points if e <= target]
                reported = cost[m][j]
                if reachable and reported < 0:
                    failures.append(f"{label} at {target:g} m: runs reach it (cheapest {min(reachable):.3f} s) "
                                    "but no time is reported")
                if not reachable and reported >= 0:
                    failures.append(f"{label} at {target:g} m: {reported:.3f} s reported but no run reaches it")
                if reported >= 0:
                    for c in reachable:
                        if c < reported * (1 - 1e-12):
                            failures.append(f"{label} at {target:g} m: a run takes {c:.4f} s < {reported:.4f} s "
                                            "and meets the target")
                    if bound[m][j] and abs(reported - min(c for c, _ in points)) > 1e-12 * reported:
                        failures.append(f"{label} at {target:g} m: upper bound {reported} s is not its cheapest run")
                checked += 1
    for line in failures:
        print(f"{path}: {line}")
    print(f"{path}: {checked} method x target cells checked, {len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
