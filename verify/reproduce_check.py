#!/usr/bin/python3
"""Recomputes stored runs of a result file with the script
`clothbench_inspect FILE command RUN` prints, and checks that each
recomputed end state (positions and velocities at t_end) and its step,
update and CG-iteration counts equal the stored ones bit for bit: runs are
deterministic on one build and thread count (h5py).

    reproduce_check.py INSPECT RESULT.h5 WORKDIR [--all]

Without --all, the first run of every label (its largest h or rtol, the
cheapest); with --all, every run. Exit 0 if every run matches, 1 with one
line per mismatch otherwise."""
import os
import subprocess
import sys

import h5py
import numpy as np


def text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def end_state(group):
    state = []
    for name in ("positions", "velocities"):
        key = name if name in group else name + "_ends"
        state.append(group[key][-1])
    return state, [int(group.attrs[k]) for k in ("steps", "fixed_point_updates", "cg_iterations")]


def main(inspect, path, workdir, every):
    failures, checked = [], 0
    with h5py.File(path, "r") as f:
        seen = set()
        ids = []
        for rid, g in f["runs"].items():
            label = text(g.attrs["label"])
            if every or label not in seen:
                ids.append(rid)
            seen.add(label)
        for rid in ids:
            rerun = os.path.join(workdir, rid)
            script = subprocess.run([inspect, path, "command", rid, "--dir", rerun], capture_output=True, text=True)
            if script.returncode != 0:
                failures.append(f"{rid}: clothbench_inspect command exit {script.returncode}: {script.stderr.strip()}")
                continue
            run = subprocess.run(["sh", "-c", script.stdout], capture_output=True, text=True)
            if run.returncode != 0:
                failures.append(f"{rid}: the script exits {run.returncode}: {run.stderr.strip()}")
                continue
            with h5py.File(os.path.join(rerun, "run.h5"), "r") as g:
                (new_id,) = list(g["runs"])
                (xa, va), ca = end_state(f["runs"][rid])
                (xb, vb), cb = end_state(g["runs"][new_id])
            checked += 1
            if new_id != rid:
                failures.append(f"{rid}: recomputed as run {new_id}")
            if ca != cb:
                failures.append(f"{rid}: steps, updates, CG iterations {ca} stored, {cb} recomputed")
            if not (np.array_equal(xa, xb) and np.array_equal(va, vb)):
                failures.append(f"{rid}: end state differs: {np.abs(xa - xb).max():.3e} m, "
                                f"{np.abs(va - vb).max():.3e} m/s")
    for line in failures:
        print(line)
    print(f"{checked} of {len(ids)} runs recomputed, {len(failures)} mismatches")
    return 1 if failures or checked == 0 else 0


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--all"]
    if len(args) != 3:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(*args, every="--all" in sys.argv[1:]))
