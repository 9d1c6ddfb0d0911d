"""Planted output targets, through every command that writes a file (run by ctest as python.pytest).

For every output path of every command (bench_integrators --out and
--series, stress_stability --out, clothbench_inspect rerun --out and export
--obj/--ply, contact_replay save --out, the module's write_results) one of
these is planted before the command runs:
  - a symbolic link at the output's temporary "<out>.tmp" (and at the output
    itself) pointing at a victim file;
  - a device node (a copy of /dev/null's numbers; root only);
  - a FIFO;
  - a folder;
  - one of the command's own inputs (the scene file, the result file read).
Every command must refuse before computing: exit 2 with one line on stderr
(Python: ValueError), and no planted target may change: the victim keeps
its bytes, the FIFO, device and folder stay what they were, the input keeps
its bytes.
"""
import os
import shutil
import stat
import subprocess

import pytest

import clothbench

BIN = os.path.dirname(os.environ["CLOTHBENCH_BENCH_INTEGRATORS"])

TINY = """name = "tiny"
t_end = 0.02
frame_dt = 0.01
h = 0.01
[grid]
nu = 4
nv = 3
size = [0.3, 0.2]
[material]
tension = [100.0, 100.0]
tension_damping = 0.1
shear = 1.0
bend = [1e-5, 1e-5]
[constraints]
fixed = ["corner:u0v1", "corner:u1v1"]
"""

PLANTS = ["tmp_symlink", "symlink", "device", "fifo", "folder"]


def run_binary(name, args, cwd):
    return subprocess.run([os.path.join(BIN, name)] + args, cwd=cwd, capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """A small result file (one sbdf2 run of the tiny scene) to read, rerun and export from."""
    d = tmp_path_factory.mktemp("stored")
    (d / "tiny.toml").write_text(TINY)
    p = run_binary("bench_integrators", ["--scene", "tiny.toml", "--integrators", "sbdf2", "--h", "0.01",
                                         "--reference", "none", "--repeat", "1", "--out", "r.h5", "--quiet"], d)
    assert p.returncode == 0, p.stderr
    runs = clothbench.read_results(str(d / "r.h5"))["runs"]
    return d / "r.h5", runs[0]["id"]


def commands(stored_file, run_id):
    """(name, argv builder, output path relative to the work folder, the inputs as copied there)."""
    return [
        ("bench_integrators --out", lambda o: ["bench_integrators", "--scene", "tiny.toml", "--integrators", "sbdf2",
                                               "--h", "0.01", "--reference", "none", "--repeat", "1", "--out", o],
         "tiny.toml"),
        ("bench_integrators --series", lambda o: ["bench_integrators", "--scene", "tiny.toml", "--integrators", "sbdf2",
                                                  "--h", "0.01", "--reference", "none", "--repeat", "1", "--out",
                                                  "o.h5", "--series", o], "tiny.toml"),
        ("stress_stability --out", lambda o: ["stress_stability", "--scenes", "tiny.toml", "--integrators", "sbdf2",
                                              "--h", "0.01", "--stiffness", "1", "--steps", "2", "--out", o],
         "tiny.toml"),
        ("inspect rerun --out", lambda o: ["clothbench_inspect", "r.h5", "rerun", run_id, "--out", o], "r.h5"),
        ("inspect export --obj", lambda o: ["clothbench_inspect", "r.h5", "export", run_id, "--frame", "0", "--obj", o],
         "r.h5"),
        ("inspect export --ply", lambda o: ["clothbench_inspect", "r.h5", "export", run_id, "--frame", "0", "--ply", o],
         "r.h5"),
        # Its input case reads the scene from "out_0.state", the name its first state gets.
        ("contact_replay save --out", lambda o: ["contact_replay", "save", "--scene", "out_0.state", "--at", "0.01",
                                                 "--out", o[:-len("_0.state")]], "out_0.state"),
    ]


OUTPUT_NAME = {"bench_integrators --out": "out.h5", "bench_integrators --series": "series.csv",
               "stress_stability --out": "out.h5", "inspect rerun --out": "out.h5", "inspect export --obj": "out.obj",
               "inspect export --ply": "out.ply", "contact_replay save --out": "out_0.state"}


def plant(kind, work, out):
    """Plants `kind` at `out` (or its temporary); returns a function that says whether it is unchanged."""
    target = work / out
    if kind in ("tmp_symlink", "symlink"):
        victim = work / "victim.txt"
        victim.write_text("victim\n")
        link = work / (out + ".tmp") if kind == "tmp_symlink" else target
        os.symlink("victim.txt", link)
        return lambda: victim.read_text() == "victim\n" and os.path.islink(link)
    if kind == "device":
        os.mknod(target, 0o600 | stat.S_IFCHR, os.makedev(1, 3))  # /dev/null's numbers
        return lambda: stat.S_ISCHR(os.lstat(target).st_mode)
    if kind == "fifo":
        os.mkfifo(target)
        return lambda: stat.S_ISFIFO(os.lstat(target).st_mode)
    assert kind == "folder"
    os.mkdir(target)
    (target / "inside").write_text("kept\n")
    return lambda: (target / "inside").read_text() == "kept\n"


CASES = [(c, k) for c in OUTPUT_NAME for k in PLANTS + ["input"]]


@pytest.mark.parametrize("command,kind", CASES, ids=[f"{c}|{k}" for c, k in CASES])
def test_a_planted_output_is_refused_and_left_unchanged(command, kind, stored, tmp_path):
    if kind == "device" and os.geteuid() != 0:
        pytest.skip("a device node is made by root only")
    stored_file, run_id = stored
    work = tmp_path
    for scene in ("tiny.toml", "out_0.state", "scene.toml"):
        (work / scene).write_text(TINY)
    shutil.copy(stored_file, work / "r.h5")
    _, argv, input_name = next(c for c in commands(stored_file, run_id) if c[0] == command)
    if kind == "input":
        out = input_name
        before = (work / input_name).read_bytes()
        unchanged = lambda: (work / input_name).read_bytes() == before  # noqa: E731
        args = argv(out if command != "contact_replay save --out" else "out_0.state")
    else:
        out = OUTPUT_NAME[command]
        if command == "contact_replay save --out":
            os.remove(work / "out_0.state")  # the output's own name: planted below
        unchanged = plant(kind, work, out)
        args = argv(out)
        if command == "contact_replay save --out":
            args[args.index("out_0.state")] = "scene.toml"
    p = run_binary(args[0], args[1:], work)
    assert p.returncode == 2, (args, p.returncode, p.stdout, p.stderr)
    assert p.stderr.count("\n") == 1, p.stderr
    assert unchanged(), (args, os.listdir(work))


@pytest.mark.parametrize("kind", PLANTS + ["input"])
def test_write_results_refuses_a_planted_target(kind, tmp_path):
    if kind == "device" and os.geteuid() != 0:
        pytest.skip("a device node is made by root only")
    scene_file = tmp_path / "tiny.toml"
    scene_file.write_text(TINY)
    scene = clothbench.load_scene(str(scene_file))  # notes the scene file as an input
    r = clothbench.run(scene, "sbdf2", h=0.01, repeat=1)
    if kind == "input":
        before = scene_file.read_bytes()
        target, unchanged = str(scene_file), lambda: scene_file.read_bytes() == before
    else:
        unchanged = plant(kind, tmp_path, "w.h5")
        target = str(tmp_path / "w.h5")
    with pytest.raises(ValueError, match="path"):
        clothbench.write_results(target, scene, [r])
    assert unchanged()


# Readers that cannot block: a result file with an external link, or with a
# virtual dataset whose source is a FIFO in another file, is refused by every
# reader (the link and the dataset's layout are checked before any read).
READERS = [["summary"], ["table"], ["runs", "--json"], ["diff", "r.h5"], ["rerun", "RUN"], ["verdict"]]


def resign(path):
    """Writes the integrity block of an edited result file again (docs/guide/results-schema.md)."""
    import zlib
    data = bytearray(open(path, "rb").read())
    block = 512
    crc = zlib.crc32(bytes(data[block:])) & 0xFFFFFFFF
    head = f"clothbench result crc32 {crc:08x} bytes {len(data)}\n".encode()
    data[:block] = head + b"\0" * (block - len(head))
    open(path, "wb").write(bytes(data))


@pytest.mark.parametrize("kind", ["external_link", "virtual_fifo"])
def test_readers_refuse_foreign_references_within_10_s(kind, stored, tmp_path):
    import h5py
    import time
    stored_file, run_id = stored
    shutil.copy(stored_file, tmp_path / "r.h5")
    bad = tmp_path / "bad.h5"
    shutil.copy(stored_file, bad)
    fifo = tmp_path / "src.h5"
    os.mkfifo(fifo)
    with h5py.File(bad, "r+") as f:
        if kind == "external_link":
            f["runs"][run_id]["elsewhere"] = h5py.ExternalLink(str(fifo), "/data")
        else:
            layout = h5py.VirtualLayout(shape=(4,), dtype="f8")
            layout[:] = h5py.VirtualSource(str(fifo), "data", shape=(4,))
            f["runs"][run_id].create_virtual_dataset("foreign", layout)
    resign(bad)
    for args in READERS:
        args = [run_id if a == "RUN" else a for a in args]
        t0 = time.monotonic()
        p = run_binary("clothbench_inspect", [str(bad)] + args, tmp_path)
        assert time.monotonic() - t0 < 10.0, args
        assert p.returncode == 2, (args, p.returncode, p.stderr)
        assert p.stderr.count("\n") == 1 and ("link" in p.stderr or "virtual dataset" in p.stderr), p.stderr
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="link|virtual dataset"):
        clothbench.read_results(str(bad))
    assert time.monotonic() - t0 < 10.0
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


# Python's array arguments are checked before use: shape, dtype, finiteness.
def test_error_rms_checks_its_arrays():
    import numpy as np
    assert clothbench.error_rms(np.zeros((2, 3)), np.ones((2, 3))) == pytest.approx(3 ** 0.5)
    for x, ref, named in [(np.zeros((2, 3)), np.ones((5, 3)), "ref"), (np.zeros((1, 3)), np.ones((50, 3)), "ref"),
                          (np.zeros((2, 2)), np.ones((2, 3)), "x"), (np.zeros((4,)), np.ones((4,)), "x"),
                          (np.full((2, 3), np.nan), np.ones((2, 3)), "x"), (np.zeros((2, 3)), np.full((2, 3), np.inf), "ref"),
                          (np.zeros((0, 3)), np.zeros((0, 3)), "x")]:
        with pytest.raises(ValueError, match=f"^{named}:"):
            clothbench.error_rms(x, ref)
    with pytest.raises(TypeError, match="^x:"):
        clothbench.error_rms(np.array([["a", "b", "c"]]), np.ones((1, 3)))


def test_run_checks_the_reference_arrays():
    import numpy as np
    scene = clothbench.load_scene(TINY)
    ref = clothbench.reference(scene, rtol=1e-6)
    r = clothbench.run(scene, "sbdf2", h=0.01, reference=ref, repeat=1)
    assert r["status"] == "ok" and r["error_final_m"] is not None
    for key, value in [("positions", np.full_like(ref["positions"], np.nan)), ("positions", ref["positions"][:, :2]),
                       ("velocities", np.zeros_like(ref["velocities"])), ("positions", ref["positions"][:1])]:
        bad = dict(ref)
        bad[key] = value
        with pytest.raises(ValueError, match=f'^reference\\["{key}"\\]'):
            clothbench.run(scene, "sbdf2", h=0.01, reference=bad, repeat=1)


def test_scene_arguments_beyond_64_bits_are_value_errors():
    with pytest.raises(ValueError, match="^particles:"):
        clothbench.load_scene("swinging_sheet", particles=2 ** 64)
    with pytest.raises(TypeError, match="^overrides: key 1"):
        clothbench.load_scene("swinging_sheet", {1: 2})
    with pytest.raises(ValueError, match="64 bits"):
        clothbench.load_scene("swinging_sheet", {"grid.nu": 2 ** 70})
    # The documented limit itself is accepted (the rounded grid stays within it).
    assert clothbench.load_scene("swinging_sheet", particles=10 ** 7).num_particles <= 10 ** 7


def test_empty_values_and_thread_counts_are_refused(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    base = ["--scene", "tiny.toml", "--integrators", "sbdf2", "--reference", "none", "--out", "o.h5"]
    for args, named in [(["--h", ""], "--h"), (["--h", "0.01,,0.02"], "--h"), (["--table", ""], "--table"),
                        (["--h", "0.01", "--targets", "1e308"], "--targets")]:
        p = run_binary("bench_integrators", base + args, tmp_path)
        assert p.returncode == 2 and p.stderr.count("\n") == 1 and named in p.stderr, (args, p.stderr)
    for threads in ["1025", "99999999999", "0", "x", ""]:
        p = subprocess.run([os.path.join(BIN, "bench_integrators")] + base + ["--h", "0.01"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=60, env=dict(os.environ, OMP_NUM_THREADS=threads))
        assert p.returncode == 2 and "OMP_NUM_THREADS" in p.stderr, (threads, p.stderr)
    p = run_binary("contact_replay", ["save", "--scene", "tiny.toml", "--at", "0.01,,0.02", "--out", "s"], tmp_path)
    assert p.returncode == 2 and "--at" in p.stderr, p.stderr
    assert not os.path.exists(tmp_path / "o.h5")
