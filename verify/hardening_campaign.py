#!/usr/bin/env python3
"""Bad-input campaign over bench_integrators, stress_stability and
clothbench_inspect, as a new user would try them: the CLI, the scene and mesh
files, the journals, the result files and the environment (docs/notes/verification.md,
"Bad input, blow-ups and limits").

Every case names what a serious tool does with it (refuse it before computing
with one line naming the option, key or file; recompute a damaged journal
entry saying so; refuse a damaged result file with one line; report a full
disk with one line and nothing half-written left). Each outcome is put in one
class:

  ok          as expected
  crash       killed by a signal (SIGSEGV, SIGFPE, ...)
  hang        still running after the time limit of the case
  unchecked   exit 0 although the input was damaged and nothing said so
              (a file built from data nobody checked)
  late        accepted, computed, then failed (exit 1) where the input could
              have been refused before computing
  unclear     refused, but not in one line naming what the case names
  leftover    a refused or failed run left .tmp, .part, .lock or a journal of
              nothing

Usage: verify/hardening_campaign.py BIN_DIR [WORK_DIR]
BIN_DIR holds bench_integrators, stress_stability and clothbench_inspect (a
build's bench/ folder). Prints one line per case and the counts per class.
"""
import collections
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

# The 4×3 sheet of verify/cli_helpers.h (kTinyScene) without its [solver]
# table, so that cases can append their own.
TINY = """name = "tiny"
t_end = 0.04
frame_dt = 0.01
h = 0.01
[grid]
nu = 4
nv = 3
size = [0.3, 0.2]
origin = [0.0, 0.0, 1.0]
u_axis = [1.0, 0.0, 0.0]
v_axis = [0.0, 1.0, 0.0]
[material]
density = 1.0
tension = [100.0, 100.0]
shear = 1.0
bend = [1e-5, 1e-5]
[forces]
gravity = [0.0, 0.0, -9.81]
[constraints]
fixed = ["corner:u0v1", "corner:u1v1"]
"""
ROWS = "--integrators sbdf2,bdf2 --h 0.01,0.005 --reference none --quiet"


class Campaign:
    def __init__(self, bins, work):
        self.bins = pathlib.Path(bins).resolve()
        self.work = pathlib.Path(work)
        shutil.rmtree(self.work, ignore_errors=True)
        self.work.mkdir(parents=True)
        self.results = []
        self.tiny = self.write("tiny.toml", TINY)

    def write(self, name, text, mode="w"):
        p = self.work / name
        with open(p, mode) as f:
            f.write(text)
        return p

    def run(self, cmd, timeout=60, shell_prefix=""):
        """Runs `cmd` (a string, in WORK_DIR) under sh; (code, stderr, stdout, hung)."""
        full = shell_prefix + cmd
        p = subprocess.Popen(["sh", "-c", full], cwd=self.work, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             start_new_session=True)
        try:
            out, err = p.communicate(timeout=timeout)
            return p.returncode, err.decode(errors="replace"), out.decode(errors="replace"), False
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.communicate()
            return None, "", "", True

    def leftovers(self, out):
        left = []
        for suffix in (".tmp", ".lock", ".journal"):
            q = pathlib.Path(str(out) + suffix)
            if q.exists() or q.is_symlink():
                left.append(q.name)
        return left

    def record(self, name, cls, detail=""):
        self.results.append((name, cls))
        print(f"{cls:<9} {name}: {detail}"[:300])

    def classify(self, name, code, err, hung, expect, needle="", out=None, allow_journal=False):
        """expect: 'refuse' (exit 2, one line with needle, no leftovers),
        'recompute' (exit 0 and a line with needle), 'ok' (exit 0)."""
        lines = [l for l in err.splitlines() if l.strip()]
        left = [l for l in (self.leftovers(out) if out else []) if not (allow_journal and l.endswith(".journal"))]
        if hung:
            return self.record(name, "hang", "no exit within the limit")
        if code is not None and code < 0 or (code is not None and code >= 128):
            return self.record(name, "crash", f"exit {code}: {err.strip()[-160:]}")
        if expect == "refuse":
            if code == 0:
                return self.record(name, "unchecked", "exit 0")
            if code == 1:
                return self.record(name, "late", lines[-1] if lines else "")
            if code != 2 or len(err.splitlines()) != 1 or needle not in err or "\u2028" in err:
                return self.record(name, "unclear", f"exit {code}: {err.strip()[:200]!r}")
        elif expect == "recompute":
            if code != 0:
                return self.record(name, "late" if code == 1 else "unclear", f"exit {code}: {err.strip()[:200]}")
            if needle not in err and needle not in "":
                return self.record(name, "unchecked", "exit 0 without saying anything was recomputed")
        elif expect == "write_failure":
            if code != 1 or len(lines) != 1 or needle not in err:
                return self.record(name, "unclear", f"exit {code}: {err.strip()[:200]}")
        if left:
            return self.record(name, "leftover", " ".join(left))
        self.record(name, "ok", (lines[-1] if lines else "")[:160])

    def bench(self, args, **kw):
        return self.run(f"{self.bins}/bench_integrators {args}", **kw)

    # -- the cases --------------------------------------------------------

    def cli_and_scenes(self):
        out = self.work / "r.h5"
        t = f"--scene {self.tiny}"
        fixed = self.write("fixed.toml", TINY.replace('fixed = [', 'fixed = ["edge:v0", "edge:v1", "edge:u0", "edge:u1", "particle:1,1", "particle:2,1", '))
        long_name = self.write("long.toml", TINY.replace('name = "tiny"', 'name = "' + "n" * 70000 + '"'))
        err_scene = self.write("err.toml", TINY + '[solver]\nstep_control = "error"\n')
        sep = self.write("sep.toml", 'name = "a\u2028\n')
        cases = [
            ("all particles fixed, default rows", f"--scene {fixed}", "constraints.fixed"),
            ("run ids that print alike", f"{t} {ROWS.replace('0.01,0.005', '0.01,0.0100000000001')}", "--h"),
            ("unwritable --series", f"{t} {ROWS} --series /proc/nonexistent/s.csv", "--series"),
            ("scene name of 70 KiB", f"--scene {long_name} {ROWS}", "name"),
            ("error control with a method that cannot use it", f"--scene {err_scene} --integrators imex_euler --h 0.01 --reference none", "step_control"),
            ("--table with options it ignores", "--table 3.1 --integrators sbdf2", "--table"),
            ("empty inner list item", f"{t} --integrators sbdf2 --h 0.01,,0.02 --reference none", "--h"),
            ("empty list", f"{t} --integrators cvode --rtols '' --reference none", "--rtols"),
            ("trailing comma", f"{t} --integrators sbdf2 --h 0.01, --reference none", "--h"),
            ("reference rtol 1e-300", f"{t} --integrators sbdf2 --h 0.01 --reference-rtol 1e-300", "--reference-rtol"),
            ("TOML error with U+2028", f"--scene {sep} {ROWS}", "sep.toml"),
        ]
        # Meshes: a header announcing 2e9 vertices, a folder, a FIFO, a symlink loop.
        (self.work / "meshdir").mkdir()
        os.mkfifo(self.work / "fifo.off")
        os.symlink("loop_b", self.work / "loop_a")
        os.symlink("loop_a", self.work / "loop_b")
        self.write("huge.off", "OFF\n2000000000 1 0\n0 0 0\n")
        for label, path in [("mesh header announcing 2e9 vertices", "huge.off"), ("folder as mesh", "meshdir"),
                            ("FIFO as mesh", "fifo.off"), ("symlink loop as mesh", "loop_a")]:
            scene = self.write(f"mesh_{path}.toml", TINY + f'[[obstacle]]\ntype = "mesh"\npath = "{self.work / path}"\ncollision_distance = 0.01\n')
            cases.append((label, f"--scene {scene} {ROWS}", "obstacle[0].path"))
        cases.append(("symlink loop as scene", f"--scene {self.work / 'loop_a'} {ROWS}", "loop_a"))
        for name, args, needle in cases:
            for p in self.work.glob("r.*"):
                shutil.rmtree(p) if p.is_dir() else p.unlink()
            code, err, _, hung = self.bench(f"{args} --out {out}", timeout=120)
            self.classify(name, code, err, hung, "refuse", needle, out)
        # Output paths that stand as something else or that the file system refuses.
        for name, prep, o in [("folder at <out>.tmp", "a.h5.tmp", "a.h5"), ("folder at <out>.xdmf", "b.xdmf", "b.h5")]:
            (self.work / prep).mkdir()
            code, err, _, hung = self.bench(f"{t} {ROWS} --out {self.work / o}")
            self.classify(name, code, err, hung, "refuse", "--out", None)
        code, err, _, hung = self.bench(f"{t} {ROWS} --out {self.work / ('x' * 300 + '.h5')}")
        self.classify("over-long --out name", code, err, hung, "refuse", "--out", None)
        jk = self.work / "k.h5.journal"
        (jk / "key").mkdir(parents=True)
        code, err, _, hung = self.bench(f"{t} {ROWS} --out {self.work / 'k.h5'}")
        self.classify("journal key that is a folder", code, err, hung, "refuse", "key", None)

    def journals(self):
        t = f"--scene {self.tiny}"
        clean = self.work / "clean.h5"
        self.bench(f"{t} {ROWS} --out {clean}")
        out = self.work / "j.h5"
        journal = pathlib.Path(str(out) + ".journal")
        variants = ["flip", "flip64", "fifo", "symlink", "cut"]
        for v in variants:
            shutil.rmtree(journal, ignore_errors=True)
            for p in (out, pathlib.Path(str(out) + ".lock")):
                p.unlink(missing_ok=True)
            self.bench(f"{t} {ROWS} --max-runs 2 --out {out}")
            entry = journal / "1.run"
            if v.startswith("flip"):
                data = bytearray(entry.read_bytes())
                for k in range(1 if v == "flip" else 64):
                    data[len(data) // 2 + 13 * k] ^= 1 << (k % 8)
                entry.write_bytes(bytes(data))
            elif v == "fifo":
                entry.unlink()
                os.mkfifo(entry)
            elif v == "symlink":
                entry.unlink()
                os.symlink(journal / "0.run", entry)
            elif v == "cut":
                entry.write_bytes(entry.read_bytes()[:-40])
            code, err, _, hung = self.bench(f"{t} {ROWS} --out {out}", timeout=60)
            self.classify(f"journal entry: {v}", code, err, hung, "recompute", "again", out)
        shutil.rmtree(journal, ignore_errors=True)
        journal.mkdir()
        (journal / "0.run").write_bytes(b"x" * 100)
        code, err, _, hung = self.bench(f"{t} {ROWS} --out {out}")
        self.classify("journal folder without key", code, err, hung, "refuse", "key", None)
        # stress_stability: an unknown outcome code and a FIFO in place of its journal.
        sweep = f"{self.bins}/stress_stability --scenes hanging_sheet --integrators sbdf2 --stiffness 1,10,100 --h 0.01 --steps 5 --side 3"
        sout = self.work / "s.h5"
        self.run(f"{sweep} --max-cells 2 --out {sout}")
        sj = pathlib.Path(str(sout) + ".journal")
        lines = sj.read_text().splitlines()
        parts = lines[-1].split(" ")
        parts[2] = "77"
        sj.write_text("\n".join(lines[:-1] + [" ".join(parts)]) + "\n")
        code, err, _, hung = self.run(f"{sweep} --out {sout}")
        self.classify("stress journal line with outcome 77", code, err, hung, "recompute", "again", sout)
        sj.unlink(missing_ok=True)
        sout.unlink(missing_ok=True)
        os.mkfifo(sj)
        code, err, _, hung = self.run(f"{sweep} --out {sout}", timeout=30)
        sj.unlink(missing_ok=True)
        self.classify("FIFO as stress journal", code, err, hung, "refuse", "s.h5.journal", sout)
        # A second writer while the first runs.
        first = subprocess.Popen(["sh", "-c", f"exec {sweep.replace('--steps 5 --side 3', '--steps 200000 --side 10')} --out {self.work / 'w.h5'}"],
                                 cwd=self.work, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(1.5)
        code, err, _, hung = self.bench(f"{t} {ROWS} --out {self.work / 'w.h5'}")
        first.send_signal(signal.SIGINT)
        first.wait()
        self.classify("second writer of the same --out", code, err, hung, "refuse", str(first.pid), None)

    def result_files(self):
        t = f"--scene {self.tiny}"
        f = self.work / "res.h5"
        self.bench(f"{t} {ROWS} --frames all --out {f}")
        data = f.read_bytes()
        insp = f"{self.bins}/clothbench_inspect"
        for k in range(12):
            g = self.work / f"flip{k}.h5"
            d = bytearray(data)
            at = 600 + (len(d) - 700) * k // 12
            for j in range(8):
                d[at + j] ^= 0x5A
            g.write_bytes(bytes(d))
            code, err, _, hung = self.run(f"{insp} {g} summary; {insp} {g} export sbdf2_h0.01 --frame 1 --obj {g}.obj", timeout=30)
            self.classify(f"inspect: 8 bytes flipped at {at}", code, err, hung, "refuse_inspect", str(g))
        for cut in (len(data) // 3, len(data) - 100):
            g = self.work / f"cut{cut}.h5"
            g.write_bytes(data[:cut])
            code, err, _, hung = self.run(f"{insp} {g} summary", timeout=30)
            self.classify(f"inspect: truncated to {cut} bytes", code, err, hung, "refuse_inspect", str(g))
        try:
            import h5py
            g = self.work / "empty_times.h5"
            shutil.copy(f, g)
            with h5py.File(g, "r+") as h:
                del h["runs/sbdf2_h0.005/times"]
                h.create_dataset("runs/sbdf2_h0.005/times", shape=(0,), dtype="f8")
            code, err, _, hung = self.run(f"{insp} {g} export sbdf2_h0.005 --frame 0 --obj {g}.obj", timeout=30)
            self.classify("inspect: export from an empty times dataset", code, err, hung, "refuse_inspect", str(g))
        except ImportError:
            pass

    def environment(self):
        t = f"--scene {self.tiny}"
        d = self.work / "full"
        d.mkdir()
        out = d / "r.h5"
        code, err, _, hung = self.run(f"ulimit -f 40 && {self.bins}/bench_integrators {t} --integrators sbdf2,bdf2 "
                                      f"--h 0.01,0.005 --frames all --quiet --out {out}")
        self.classify("file-size limit at write time", code, err, hung, "write_failure", str(out), out,
                      allow_journal=True)
        p = subprocess.Popen(["sh", "-c", f"exec {self.bins}/bench_integrators --table 3.1 --out {self.work / 't.h5'}"],
                             cwd=self.work, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        time.sleep(2)
        p.send_signal(signal.SIGTERM)
        err = p.communicate()[1].decode(errors="replace")
        ok = ".journal" not in err or pathlib.Path(str(self.work / "t.h5") + ".journal").exists()
        self.record("SIGTERM under --table", "ok" if ok else "unclear", err.strip()[:160])


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        return 2
    c = Campaign(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else "/tmp/clothbench_campaign")
    orig = c.classify

    def classify(name, code, err, hung, expect, needle="", out=None, allow_journal=False):
        if expect == "refuse_inspect":  # inspect: exit 2, one line naming the file, per command
            lines = [l for l in err.splitlines() if l.strip()]
            if hung:
                return c.record(name, "hang")
            if code is not None and (code < 0 or code >= 128):
                return c.record(name, "crash", f"exit {code}")
            if code == 0:
                return c.record(name, "unchecked", "exit 0")
            if code != 2 or not lines or any(needle not in l for l in lines):
                return c.record(name, "unclear", f"exit {code}: {err.strip()[:200]!r}")
            return c.record(name, "ok", lines[-1][:160])
        return orig(name, code, err, hung, expect, needle, out, allow_journal)

    c.classify = classify
    for part in (c.cli_and_scenes, c.journals, c.result_files, c.environment):
        part()
    counts = collections.Counter(cls for _, cls in c.results)
    print("\n" + ", ".join(f"{k} {counts.get(k, 0)}" for k in
                           ("ok", "crash", "hang", "unchecked", "late", "unclear", "leftover")) +
          f"; {len(c.results)} cases")
    return 0


if __name__ == "__main__":
    sys.exit(main())
