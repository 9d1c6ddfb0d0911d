"""Bad run requests through every entry point (run by ctest as python.pytest).

One table of bad values per request field (harness/run_request.h) is sent
through the five entry points: bench_integrators, stress_stability,
contact_replay, the module's run/reference/write_results, and the rerun of
a stored run (clothbench_inspect FILE rerun RUN, with the value edited into
the file and the file signed again). Each must be refused before anything
is computed: exit 2 with one line on stderr naming the field as that entry
point names it (Python: ValueError or TypeError naming the keyword), no
output file, no progress callback called.
"""
import math
import os
import shutil
import subprocess
import zlib

import h5py
import numpy as np
import pytest

import clothbench

BIN = os.path.dirname(os.environ["CLOTHBENCH_BENCH_INTEGRATORS"])
NAN, INF = math.nan, math.inf

# field: bad values. The swinging sheet has t_end = 1 s and h = 0.01 s.
BAD = {
    "method": ["no_such", "", "SBDF2", "sbdf2 ", "arkode/ark9", "sbdf2/newton", "xpbd/error", "cvode/klu/klu",
               "imex_euler/fixed_point", "bdf2/newton/newton", "$(touch MARKER)"],
    "h": [0.0, -0.01, NAN, INF, 1e-300, 2.0],
    "rtol": [0.0, 2.0, NAN, -1e-3, 1e-300],
    "t_end": [0.0, -1.0, NAN, INF, 2e6],
    "preconditioner": ["lu", "", "IC0", "ic0;x"],
    "cg_tolerance": [0.0, 1.0, NAN, -1e-6],
    "tangent_terms": ["some", ""],
    "substeps": [0, -1, 2000000],
    "iterations": [0, -1, 2000000],
    "time_limit": [0.0, NAN, -1.0, INF],
    "repeat": [0, 1001, -1],
    "time_budget": [NAN, -1.0, 2e6],
    "arkode_table": ["ARK999", ""],
    "cvode_setting": ["foo=1", "lsetup_frequency", "lsetup_frequency=x"],
    "self_contact": ["maybe", "", "ON"],
}
# The row whose request reads the field, and its step (or rtol).
ROW = {"rtol": ("cvode", {}), "arkode_table": ("arkode", {"rtol": 1e-3}), "cvode_setting": ("cvode", {"rtol": 1e-3}),
       "tangent_terms": ("bdf2/newton", {"h": 0.01}), "substeps": ("xpbd", {"h": 0.01}),
       "iterations": ("pd", {"h": 0.01})}
OPTION = {"method": "--integrators", "h": "--h", "rtol": "--rtols", "t_end": "--t-end",
          "preconditioner": "--preconditioner", "cg_tolerance": "--cg-tolerance", "tangent_terms": "--tangent-terms",
          "substeps": "--substeps", "iterations": "--iterations", "time_limit": "--time-limit", "repeat": "--repeat", "time_budget": "--time-budget",
          "arkode_table": "--arkode-table", "cvode_setting": "--cvode-setting", "self_contact": "--self-contact"}


def cases():
    return [(field, value) for field, values in BAD.items() for value in values]


def text(value):
    return repr(value) if isinstance(value, float) and not math.isfinite(value) else str(value)


def cli_value(value):
    return {NAN: "nan", INF: "inf"}.get(value, str(value)) if isinstance(value, float) else str(value)


def refused(p, named):
    """exit 2, one line on stderr naming `named`."""
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    assert p.stderr.count("\n") == 1, p.stderr
    assert named in p.stderr, (named, p.stderr)


def run_binary(name, args, cwd):
    return subprocess.run([os.path.join(BIN, name)] + args, cwd=cwd, capture_output=True, text=True, timeout=60)


def test_the_table_has_at_least_30_requests_per_entry_point():
    assert len(cases()) >= 30


@pytest.mark.parametrize("field,value", cases())
def test_python_run(field, value):
    method, base = ROW.get(field, ("sbdf2", {"h": 0.01}))
    kwargs = dict(base)
    if field == "method":
        method = value
    else:
        kwargs[field] = value
    called = []
    with pytest.raises((ValueError, TypeError)) as e:
        clothbench.run("swinging_sheet", method, progress=lambda t, t_end: called.append(t), **kwargs)
    assert str(e.value).startswith(field + ":"), str(e.value)
    assert not called


def test_python_types_name_the_keyword():
    for kwargs, keyword in [({"h": "0.01"}, "h"), ({"h": 0.01, "repeat": True}, "repeat"),
                            ({"h": 0.01, "t_end": [1]}, "t_end"), ({"h": 0.01, "preconditioner": 3}, "preconditioner"),
                            ({"h": 0.01, "overrides": 3}, "overrides"), ({"h": 0.01, "progress": 3}, "progress")]:
        with pytest.raises(TypeError, match="^" + keyword + ":"):
            clothbench.run("swinging_sheet", "sbdf2", **kwargs)
    with pytest.raises(TypeError, match="^scene:"):
        clothbench.run(3, "sbdf2", h=0.01)
    with pytest.raises(TypeError, match="^method:"):
        clothbench.run("swinging_sheet", None, h=0.01)


def test_method_settings_are_keywords_of_their_rows_only():
    # The methods' own settings come from the registry: each is a run()
    # keyword and a test field above, a keyword no method declares is a
    # TypeError, and a wrong type names the keyword.
    names = clothbench.setting_names()
    assert sorted(names) == sorted(f for f in BAD if f in OPTION and f not in
                                   ("method", "h", "rtol", "t_end", "preconditioner", "cg_tolerance", "tangent_terms",
                                    "substeps", "iterations", "time_limit", "repeat", "time_budget", "self_contact"))
    with pytest.raises(TypeError, match="unexpected keyword argument 'no_such_setting'"):
        clothbench.run("swinging_sheet", "sbdf2", h=0.01, no_such_setting="x")
    for name in names:
        method, base = ROW[name]
        with pytest.raises(TypeError, match="^" + name + ":"):
            clothbench.run("swinging_sheet", method, **base, **{name: 3})


@pytest.mark.parametrize("field,value", [(f, v) for f, v in cases() if f in ("rtol", "t_end")] +
                         [("method", "sbdf2"), ("method", "no_such")])
def test_python_reference(field, value):
    kwargs = {field: value}
    with pytest.raises((ValueError, TypeError)) as e:
        clothbench.reference("swinging_sheet", **kwargs)
    assert str(e.value).startswith(field + ":"), str(e.value)


def test_python_write_results_refusals(tmp_path):
    scene = clothbench.load_scene("swinging_sheet", {"t_end": 0.05})
    run = clothbench.run(scene, "sbdf2", h=0.01)
    other = clothbench.run("hanging_sheet", "sbdf2", h=0.01, t_end=0.05)
    ref_other = clothbench.reference("swinging_sheet", t_end=0.05)  # another scene text than `scene`
    for kwargs, named, error in [
            ({"runs": [other]}, "runs:", ValueError), ({"runs": [run], "reference": ref_other}, "reference:", ValueError),
            ({"runs": [run], "frames": "some"}, "frames:", ValueError),
            ({"runs": [run], "error_metric": "rms"}, "error_metric:", ValueError),
            ({"runs": [run], "targets": [0.0]}, "targets:", ValueError),
            ({"runs": [run], "targets": "1e-3"}, "targets:", TypeError),
            ({"runs": run}, "runs:", TypeError), ({"runs": [{"id": "x"}]}, "runs:", ValueError)]:
        out = tmp_path / "w.h5"
        with pytest.raises(error, match="^" + named):
            clothbench.write_results(str(out), scene, **kwargs)
        assert not out.exists()
    with pytest.raises(TypeError, match="^path:"):
        clothbench.write_results(3, scene, [run])


@pytest.mark.parametrize("field,value", [(f, v) for f, v in cases()
                                         if f in ("method", "h", "rtol", "t_end", "preconditioner", "cg_tolerance",
                                                  "tangent_terms", "substeps", "iterations", "time_limit", "repeat",
                                                  "time_budget",
                                                  "arkode_table", "cvode_setting")])
def test_bench_integrators(field, value, tmp_path):
    method, base = ROW.get(field, ("sbdf2", {"h": 0.01}))
    args = {"method": method}
    args.update(base)
    args[field] = value
    if field == "method" and value == "sbdf2 ":
        value = args["method"] = "sbdf2 x"  # command-line lists trim their items
    argv = ["--reference", "none", "--quiet", "--out", str(tmp_path / "b.h5")]
    for k, v in args.items():
        argv += [OPTION[k], cli_value(v)]
    p = run_binary("bench_integrators", argv, tmp_path)
    refused(p, OPTION[field])
    assert not (tmp_path / "b.h5").exists()
    assert not (tmp_path / "MARKER").exists()


# Command-line lists trim their items ("sbdf2 " is sbdf2); h = 1e-300 for
# 5 steps is a valid cell.
STRESS = [("--integrators", v) for v in BAD["method"] + ["xpbd", "cvode", "sbdf2,sbdf2"] if v != "sbdf2 "] + \
         [("--h", v) for v in ["0", "-0.01", "nan", "inf", "1e300", "x"]] + \
         [("--stiffness", v) for v in ["0", "-1", "nan", "x", ""]] + \
         [("--steps", v) for v in ["0", "-5", "2000001"]] + [("--side", v) for v in ["2", "201", "x"]] + \
         [("--scenes", v) for v in ["no_such_scene", "", "hanging_sheet,hanging_sheet"]] + \
         [("--nonlinear-solver", v) for v in ["newtown", ""]]


@pytest.mark.parametrize("option,value", STRESS)
def test_stress_stability(option, value, tmp_path):
    argv = ["--integrators", "sbdf2", "--h", "0.01", "--stiffness", "1", "--steps", "5", "--out",
            str(tmp_path / "s.h5")]
    i = argv.index(option) if option in argv else None
    if i is None:
        argv += [option, value]
    else:
        argv[i + 1] = value
    p = run_binary("stress_stability", argv, tmp_path)
    named = ("--steps x --h" if option == "--h" and value == "1e300" else
             value if option == "--scenes" and value == "no_such_scene" else  # names the file
             option.lstrip("-") if option in ("--steps", "--side") else option)
    refused(p, named)
    assert not (tmp_path / "s.h5").exists()


@pytest.fixture(scope="module")
def saved_state(tmp_path_factory):
    d = tmp_path_factory.mktemp("replay")
    p = run_binary("contact_replay", ["save", "--scene", "round_table", "--at", "0.3", "--out", str(d / "rt")], d)
    assert p.returncode == 0, p.stderr
    return d / "rt_0.state"


REPLAY = [(["--integrator", v], "--integrator") for v in BAD["method"] + ["xpbd", "cvode", "baraff_witkin"]
          if v != "sbdf2 "] + \
         [(["--preconditioner", v], "--preconditioner") for v in BAD["preconditioner"]] + \
         [(["--amg-frames", v], "--amg-frames") for v in ["wobbly", "", "Spread"]] + \
         [(["--steps", v], "--steps") for v in ["0", "-1", "71", "x"]] + \
         [(["--scene", v], v) for v in ["no_such_scene", "/dev/null", "/"]]


@pytest.mark.parametrize("extra,named", REPLAY)
def test_contact_replay(extra, named, saved_state, tmp_path):
    argv = ["replay", "--scene", "round_table", "--steps", "1", "--state", str(saved_state)]
    for k in range(0, len(extra), 2):
        if extra[k] in argv:
            argv[argv.index(extra[k]) + 1] = extra[k + 1]
        else:
            argv += extra[k:k + 2]
    p = run_binary("contact_replay", argv, tmp_path)
    refused(p, named)
    assert not (tmp_path / "MARKER").exists()


def test_contact_replay_states_and_times(saved_state, tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for state, named in [(str(tmp_path), "is not a regular file"), (str(fifo), "is not a regular file"),
                         ("/dev/zero", "is not a regular file"), (str(tmp_path / "none"), "--state"),
                         ("/etc/hostname", "bytes")]:
        p = run_binary("contact_replay", ["replay", "--scene", "round_table", "--steps", "1", "--state", state],
                       tmp_path)
        refused(p, named)
    for at in ["0", "-1", "2", "nan", "0.5,0.2"]:
        p = run_binary("contact_replay", ["save", "--scene", "round_table", "--at", at, "--out", str(tmp_path / "s")],
                       tmp_path)
        refused(p, "--at")
        assert not list(tmp_path.glob("s_*"))


def sign(path):
    """Signs a result file again (docs/guide/results-schema.md, "Integrity"): the
    CRC-32 of everything past the 512-byte block and the file's size."""
    with open(path, "r+b") as f:
        data = f.read()
        block = "clothbench result crc32 {:08x} bytes {}\n".format(zlib.crc32(data[512:]), len(data)).encode()
        f.seek(0)
        f.write(block.ljust(512, b"\0"))


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    d = tmp_path_factory.mktemp("stored")
    p = run_binary("bench_integrators", ["--integrators", "sbdf2,bdf2/newton,xpbd,pd,vbd/chebyshev,arkode,cvode", "--h", "0.01",
                                         "--rtols", "1e-3", "--substeps", "2", "--iterations", "2", "--t-end", "0.05",
                                         "--reference",
                                         "none", "--quiet", "--out", str(d / "a.h5")], d)
    assert p.returncode == 0, p.stderr
    return d / "a.h5"


def edit(src, dst, obj, name, value):
    shutil.copyfile(src, dst)
    with h5py.File(dst, "r+") as f:
        a = f[obj].attrs
        del a[name]
        if isinstance(value, str):
            a.create(name, np.bytes_(value.encode() or b"\0"))
        elif isinstance(value, int):
            a.create(name, np.int64(value))
        else:
            a.create(name, np.float64(value))
    sign(dst)


# (object, attribute, run, bad stored values, the field the refusal names)
STORED = [("/runs/sbdf2_h0.01", "label", "sbdf2_h0.01", BAD["method"] + ["bdf2", "imex_euler"], "label"),
          ("/runs/sbdf2_h0.01", "h", "sbdf2_h0.01", [0.0, -0.01, NAN, INF, 1e-300, 2.0, 0.02], "h"),
          ("/runs/cvode_rtol0.001", "rtol", "cvode_rtol0.001", [0.0, 2.0, NAN, -1e-3, 1e-300], "rtol"),
          ("/runs/sbdf2_h0.01", "preconditioner", "sbdf2_h0.01", ["lu", "IC0", "ic0;x"], "preconditioner"),
          ("/runs/sbdf2_h0.01", "cg_tolerance", "sbdf2_h0.01", [0.0, 1.0, NAN, -1e-6], "cg_tolerance"),
          ("/runs/bdf2_newton_h0.01", "tangent_terms", "bdf2_newton_h0.01", ["some", "$(x)"], "tangent_terms"),
          ("/runs/xpbd_h0.01_n2", "substeps", "xpbd_h0.01_n2", [0, -1, 2000000, 3], "substeps"),
          ("/runs/pd_h0.01_k2", "iterations", "pd_h0.01_k2", [0, -1, 2000000, 3], "iterations"),
          ("/runs/vbd_chebyshev_h0.01_k2", "iterations", "vbd_chebyshev_h0.01_k2", [0, -1, 2000000, 3], "iterations"),
          ("/runs/arkode_rtol0.001", "butcher_table", "arkode_rtol0.001", ["ARK999", "x\ny"], "arkode_table"),
          ("/runs/cvode_rtol0.001", "sundials_settings", "cvode_rtol0.001", ["foo=1", "lsetup_frequency"],
           "cvode_setting"),
          ("/runs/sbdf2_h0.01", "threads", "sbdf2_h0.01", [-1, 2 ** 31, 1025], "threads"),
          ("/scene", "t_end", "sbdf2_h0.01", [0.0, -1.0, NAN, 2e6], "t_end"),
          ("/scene", "frames", "sbdf2_h0.01", ["some", "`x`"], "frames"),
          ("/scene", "n_particles", "sbdf2_h0.01", [399, 0], "particle")]


@pytest.mark.parametrize("obj,name,run,value,named",
                         [(o, n, r, v, f) for o, n, r, values, f in STORED for v in values])
def test_rerun_of_a_stored_run(obj, name, run, value, named, stored, tmp_path):
    bad = tmp_path / "bad.h5"
    edit(stored, bad, obj, name, value)
    for sub in (["rerun", run, "--out", str(tmp_path / "r.h5")], ["command", run]):
        p = run_binary("clothbench_inspect", [str(bad)] + sub, tmp_path)
        refused(p, named)
        assert p.stdout == ""
        assert not (tmp_path / "r.h5").exists()


def test_a_run_that_cannot_fit_in_memory_is_refused_at_every_door(tmp_path):
    """9·10⁶ particles (inside the 10⁷ limit): sbdf2's factor, ordering and
    workspace take about 3 kB per particle (3.00 GB peak at 10⁶,
    harness/memory_check.cc), 27 GB here, more than this machine's memory:
    refused by the request's own check before the model is built, whichever
    door (a machine with more than 34 GB available would run it)."""
    import time
    available = next(int(l.split()[1]) * 1024 for l in open("/proc/meminfo") if l.startswith("MemAvailable"))
    if available > 34e9:
        pytest.skip(f"{available / 1e9:.0f} GB available: this machine would run it")
    scene = clothbench.load_scene("large_sheet", particles=9 * 10 ** 6)
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="grid.nu × grid.nv = 3000 × 3000"):
        clothbench.run(scene, "sbdf2", h=0.01, repeat=1)
    assert time.monotonic() - t0 < 5.0
    (tmp_path / "big.toml").write_text(scene.toml)
    p = run_binary("bench_integrators", ["--scene", "big.toml", "--integrators", "sbdf2", "--h", "0.01", "--reference",
                                         "none", "--frames", "none"], tmp_path)
    refused(p, "grid.nu × grid.nv = 3000 × 3000")


def interrupt_after(code, seconds):
    """Runs `code` in a fresh interpreter, sends SIGINT `seconds` after it
    starts computing; returns (seconds from SIGINT to exit, stderr)."""
    import signal
    import time
    p = subprocess.Popen(["/usr/bin/python3", "-c", "import clothbench\nprint('ready', flush=True)\n" + code],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    assert p.stdout.readline().strip() == "ready"
    time.sleep(seconds)
    t0 = time.monotonic()
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    return time.monotonic() - t0, err


@pytest.mark.parametrize("code", [
    "clothbench.run('hanging_sheet', 'vbd', h=0.01, iterations=100000, repeat=1)",
    "clothbench.run('hanging_sheet', 'pd', h=0.01, iterations=100000, repeat=1)",
    "clothbench.run('hanging_sheet', 'xpbd', h=0.01, substeps=100000, repeat=1)",
    "import threading\nt = threading.Thread(target=lambda: clothbench.run('hanging_sheet', 'vbd', h=0.01, "
    "iterations=100000, repeat=1))\nt.start()\nt.join()",
])
def test_ctrl_c_stops_the_iterations_inside_a_step(code):
    """Our own loops (VBD's, PD's and XPBD's iterations, the PCG's) check for
    SIGINT at each iteration: the call ends with KeyboardInterrupt within
    0.2 s (measured 10-15 ms; one VBD sweep of 400 particles is 0.2 ms)."""
    took, err = interrupt_after(code, 1.5)
    assert "KeyboardInterrupt" in err, err
    assert took < 0.2 + 0.3, took  # + the interpreter's own exit


def test_ctrl_c_during_a_10_6_particle_setup_returns_after_the_library_call():
    """In a setup, SIGINT is acted on between the phases and as each library
    call returns (METIS' ordering, CHOLMOD's factorisation: neither has a
    callback). At 10⁶ particles the longest of them takes about 5 s here
    (docs/notes/performance.md: analysis 4.9 s, factorisation 3.7 s), and the
    return took 1-8.5 s over eleven times of the signal in the first 14 s:
    bound 15 s."""
    took, err = interrupt_after("clothbench.run('large_sheet', 'sbdf2', h=0.01, repeat=1)", 3.0)
    assert "KeyboardInterrupt" in err, err
    assert took < 15.0, took


TINY_SHEET = """name = "tiny"
t_end = 0.1
frame_dt = 0.01
h = 0.01
[grid]
nu = 6
nv = 6
size = [0.3, 0.3]
origin = [0.0, 0.0, 0.5]
[material]
tension = [100.0, 100.0]
tension_damping = 0.1
shear = 1.0
bend = [1e-5, 1e-5]
[constraints]
fixed = ["corner:u0v1", "corner:u1v1"]
"""


def test_a_cloth_that_starts_inside_an_obstacle_is_refused(tmp_path):
    """The sheet's middle inside a sphere of radius 0.1 m: refused before
    computing, naming the obstacle and the deepest particle (the guard's rule:
    deeper than the collision distance δ)."""
    inside = TINY_SHEET + '[[obstacle]]\ntype = "sphere"\ncenter = [0.15, 0.15, 0.5]\nradius = 0.1\n'
    with pytest.raises(ValueError, match=r"obstacle\[0\] \(sphere\): particle \d+ starts .* m inside it"):
        clothbench.run(inside, "sbdf2", h=0.01, repeat=1)
    (tmp_path / "inside.toml").write_text(inside)
    p = run_binary("bench_integrators", ["--scene", "inside.toml", "--integrators", "sbdf2", "--h", "0.01",
                                         "--reference", "none"], tmp_path)
    refused(p, "obstacle[0] (sphere): particle")
    # Touching within δ is contact, not a start inside: the sphere's top 5 mm into the sheet runs.
    touching = TINY_SHEET + '[[obstacle]]\ntype = "sphere"\ncenter = [0.15, 0.15, 0.405]\nradius = 0.1\n'
    r = clothbench.run(touching, "sbdf2", h=0.01, repeat=1)
    assert r["status"] == "ok", (r["status"], r["message"])


def test_a_keyframed_obstacle_cannot_lift_the_speed_bound(tmp_path):
    """A plane under a free sheet keyframed upward at 1000 m/s flings the
    cloth at 600-1300 m/s. Without a ceiling the obstacle's speed entered the
    bound (2 v_bound > 2000 m/s: ok runs); its share is capped at
    kMaxObstacleSpeed = 100 m/s (solver/run.h), 2 v_bound = 203 m/s, so the
    runs end `speed` (measured: sbdf2 1.31e3 m/s, xpbd 620 m/s)."""
    fast = TINY_SHEET.replace("fixed = [\"corner:u0v1\", \"corner:u1v1\"]", "fixed = []") + \
        '[[obstacle]]\ntype = "plane"\ncenter = [0.0, 0.0, 0.45]\nnormal = [0.0, 0.0, 1.0]\n' \
        'keyframes = [{ t = 0.02 }, { t = 0.03, translate = [0.0, 0.0, 10.0] }]\n'
    for method, extra in [("sbdf2", {}), ("xpbd", {"substeps": 1})]:
        r = clothbench.run(fast, method, h=1e-4, t_end=0.03, repeat=1, **extra)
        assert r["status"] == "speed", (method, r["status"], r["message"])
