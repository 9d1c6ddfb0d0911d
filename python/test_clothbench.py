"""Tests of the Python module (run by ctest as python.pytest)."""
import os
import subprocess

import h5py
import numpy as np
import pytest

import clothbench


def test_run_is_bit_identical_to_the_command_line(tmp_path):
    # The same row through bench_integrators and through the module: the
    # same harness, so every stored frame must be equal to the bit.
    out = tmp_path / "cli.h5"
    subprocess.run([os.environ["CLOTHBENCH_BENCH_INTEGRATORS"], "--integrators", "sbdf2", "--h", "0.01",
                    "--reference", "none", "--frames", "all", "--out", str(out), "--quiet"],
                   check=True, stdout=subprocess.DEVNULL)
    r = clothbench.run("swinging_sheet", "sbdf2", h=0.01)
    with h5py.File(out) as f:
        g = f["runs/sbdf2_h0.01"]
        assert np.array_equal(g["times"][:], r["times"])
        assert np.array_equal(g["positions"][:], r["positions"])
        assert np.array_equal(g["velocities"][:], r["velocities"])
        assert np.array_equal(g["step_stats"]["cg_iterations"], r["step_stats"]["cg_iterations"])
    assert r["status"] == "ok" and r["steps"] == 100
    assert r["positions"].shape == (101, 400, 3)


def test_every_row_runs_at_its_default_params_through_row_param():
    # Every registry row's default values are for the run() keyword that
    # row_param names: the first of them runs each row for one step's worth
    # of time on the swinging sheet (any refusal or failure would fail here).
    scene = clothbench.load_scene("swinging_sheet", {"t_end": 0.02})
    rows = clothbench.methods() + ["sbdf2/error"]
    for row in rows:
        key = clothbench.row_param(row)
        assert key in ("h", "rtol"), row
        params = clothbench.default_params(scene, row)
        r = clothbench.run(scene, row, **{key: params[0]})
        assert r["status"] == "ok", (row, r["message"])
        assert r[key] == params[0], row
    assert clothbench.row_param("sbdf2") == "h" and clothbench.row_param("sbdf2/error") == "rtol"
    assert clothbench.row_param("cvode") == "rtol" and clothbench.row_param("xpbd") == "h"
    with pytest.raises(ValueError, match="method"):
        clothbench.row_param("no_such")


def test_overrides_and_toml_text():
    base = clothbench.load_scene("swinging_sheet")
    heavy = clothbench.load_scene("swinging_sheet", {"material.density": 2.0, "t_end": 0.1})
    assert heavy.t_end == 0.1 and base.t_end == 1.0
    # The same scene from its TOML text runs the same trajectory.
    a = clothbench.run(base.toml, "imex_euler", h=0.01, t_end=0.05)
    b = clothbench.run("swinging_sheet", "imex_euler", h=0.01, t_end=0.05)
    assert np.array_equal(a["positions"], b["positions"])
    # A heavier sheet (same stiffness) moves differently.
    c = clothbench.run(heavy, "imex_euler", h=0.01, t_end=0.05)
    assert not np.array_equal(c["positions"][-1], b["positions"][-1])


def test_overrides_reach_a_table_of_an_array_of_tables():
    # "obstacle.0.friction" sets the first [[obstacle]]'s key; the table's
    # other keys are kept.
    s = clothbench.load_scene("round_table", {"obstacle.0.friction": 0.75})
    assert "friction = 0.75" in s.toml and "radius = 0.29999999999999999" in s.toml  # toml++ writes 17 digits
    for bad in ("obstacle.1.friction", "obstacle.x.friction", "obstacle.0"):
        with pytest.raises(ValueError, match="override"):
            clothbench.load_scene("round_table", {bad: 0.7})


def test_load_scene_refines_the_grid_as_bench_integrators_sizes():
    fine = clothbench.load_scene("swinging_sheet", particles=2500, overrides={"t_end": 0.05})
    assert fine.num_particles == 2500 and fine.name == "swinging_sheet_50x50" and fine.t_end == 0.05
    assert "nu = 50" in fine.toml
    r = clothbench.run(fine, "sbdf2", h=0.01)
    assert r["positions"].shape[1] == 2500
    with pytest.raises(ValueError, match="constraints.fixed"):
        clothbench.load_scene('[constraints]\nfixed = ["particle:1,1"]\n', particles=400)
    with pytest.raises(ValueError):
        clothbench.load_scene("swinging_sheet", particles=3)
    with pytest.raises(TypeError, match="particles"):
        clothbench.load_scene("swinging_sheet", particles=400.0)


def test_read_results_gives_the_scale_verdict_of_a_sizes_file(tmp_path):
    # bench_integrators --sizes writes one file per size and the verdict;
    # read_results gives the verdict as the file holds it: the fastest label
    # per size and target has the least cost of that cell.
    out = tmp_path / "sizes.h5"
    subprocess.run([os.environ["CLOTHBENCH_BENCH_INTEGRATORS"], "--integrators", "sbdf2,cvode", "--t-end", "0.2",
                    "--targets", "1e-2,1e-3", "--repeat", "1", "--frames", "none", "--quiet", "--sizes", "100,400",
                    "--out", str(out)], check=True, capture_output=True)
    v = clothbench.read_results(str(out))["scale_verdict"]
    assert v["sizes"] == [100, 400] and v["targets"] == [1e-2, 1e-3] and v["labels"] == ["sbdf2", "cvode"]
    assert v["result_files"] == ["sizes.n100.h5", "sizes.n400.h5"]
    for s in range(2):
        for j in range(2):
            costs = v["cost_s"][s][j]
            assert v["fastest"][s][j] == min(costs, key=costs.get)
    assert clothbench.read_results(str(tmp_path / "sizes.n400.h5"))["scene"]["n_particles"] == 400


def test_bad_input_is_refused():
    with pytest.raises(ValueError):
        clothbench.load_scene("swinging_sheet", {"material.no_such_key": 1.0})
    with pytest.raises(ValueError):
        clothbench.run("swinging_sheet", "no_such_method", h=0.01)
    with pytest.raises(ValueError):
        clothbench.run("swinging_sheet", "cvode")  # adaptive: needs rtol
    with pytest.raises(ValueError):
        clothbench.run("swinging_sheet", "sbdf2", h=0.01, preconditioner="lu")


def test_adaptive_row_and_step_stats():
    r = clothbench.run("swinging_sheet", "cvode", rtol=1e-3, t_end=0.2)
    assert r["status"] == "ok"
    s = r["step_stats"]
    assert s.dtype.names == ("t", "h", "updates", "cg_iterations", "status", "colliding", "solve_time_s",
                             "setup_time_s", "preconditioner")
    assert np.all(s["preconditioner"] == 0)  # no obstacle: the factor of A_F
    assert len(s) == r["steps"] + np.count_nonzero(s["status"] != 0)
    assert np.all(np.diff(s["t"][s["status"] == 0]) > 0)


def test_error_against_the_reference_equals_the_command_line(tmp_path):
    # e_rms(t_end) of a row against the CVODE reference: the module's
    # reference and error_rms give the value bench_integrators stores.
    out = tmp_path / "cli.h5"
    subprocess.run([os.environ["CLOTHBENCH_BENCH_INTEGRATORS"], "--integrators", "sbdf2", "--h", "0.01",
                    "--frames", "none", "--out", str(out), "--quiet"], check=True, stdout=subprocess.DEVNULL)
    ref = clothbench.reference("swinging_sheet")
    r = clothbench.run("swinging_sheet", "sbdf2", h=0.01)
    with h5py.File(out) as f:
        assert f["runs/sbdf2_h0.01"].attrs["error_final_m"] == clothbench.error_rms(r["positions"][-1],
                                                                                 ref["positions"][-1])


def test_reference_and_run_carry_the_one_record_the_file_stores(tmp_path):
    # One record from the step loop to the file and to Python: the dicts of
    # reference() and run() have the same record keys (beyond them, each
    # method's own attributes: the CVODE reference's sundials_settings),
    # and write_results stores exactly their values as /reference and
    # /runs/<id> attributes.
    scene = clothbench.load_scene("swinging_sheet", {"t_end": 0.1})
    ref = clothbench.reference(scene)
    r = clothbench.run(scene, "sbdf2", h=0.01, reference=ref)
    arrays = {"times", "positions", "velocities", "step_stats", "energy", "scene_hash", "record", "method"}
    assert set(ref) - arrays - {"sundials_settings"} <= set(r) - arrays
    assert "sundials_settings" in ref and "sundials_settings" not in r
    out = tmp_path / "one.h5"
    clothbench.write_results(str(out), scene, [r], reference=ref, frames="none")
    with h5py.File(out) as f:
        for group, d in (("reference", ref), ("runs/" + r["id"], r)):
            attrs = f[group].attrs
            for key, value in d.items():
                if key in arrays or key == "id" or value is None or key not in attrs:
                    continue
                stored = attrs[key]
                stored = stored.decode() if isinstance(stored, bytes) else stored
                assert stored == value, (group, key, stored, value)
            assert attrs["status"] == "ok" or attrs["status"] == b"ok"
            assert attrs["steps"] == d["steps"] > 0
    assert ref["integrator"] == "cvode" and ref["step_kind"] == "adaptive" and ref["rtol"] == 1e-10
    assert len(ref["step_stats"]) == ref["steps"]
    # The reference is the reduced CVODE with its error estimate (against
    # itself at rtol/10), as bench_integrators --reference cvode computes it;
    # at rtol 1e-10 over 0.1 s it is far below a micrometre.
    assert ref["label"] == "cvode" and ref["preconditioner"] == "auto"
    assert 0.0 < ref["error_estimate_m"] < 1e-8
    klu = clothbench.reference(scene, method="cvode/klu")
    assert klu["label"] == "cvode/klu" and klu["error_estimate_m"] > 0.0
    assert clothbench.error_rms(klu["positions"][-1], ref["positions"][-1]) < 1e-8


def test_equal_accuracy_interpolates_log_log():
    # "a": 1 s at 1e-2 m, 4 s at 1e-4 m; at 1e-3 m, halfway in log e, the
    # cost is the geometric mean 2 s (to round-off). "b" reaches 1e-3 m at
    # 1.5 s: it is the fastest, and the baseline (ratio 1). 1e-5 m is
    # bracketed by neither.
    t = clothbench.equal_accuracy([("a", [(1.0, 1e-2), (4.0, 1e-4)]), ("b", [(1.0, 1e-1), (1.5, 1e-3)])],
                                  targets=[1e-3, 1e-5], baseline="b")
    assert t["labels"] == ["a", "b"]
    assert abs(t["cost"][0][0] - 2.0) < 1e-12 and t["ratio"][1][0] == 1.0
    assert abs(t["ratio"][0][0] - 2.0 / 1.5) < 1e-12
    assert t["fastest"] == ["b", None] and t["cost"][0][1] is None


def test_work_precision_example_runs(tmp_path):
    example = os.path.join(os.path.dirname(__file__), "..", "examples", "work_precision.py")
    # Its own matplotlib cache: ctest runs the plot tests at the same time,
    # and two processes building one font cache can fail.
    env = dict(os.environ, MPLCONFIGDIR=str(tmp_path / "mpl"))
    p = subprocess.run(["/usr/bin/python3", example, "sbdf2", "cvode"], cwd=tmp_path, capture_output=True,
                       text=True, env=env)
    assert p.returncode == 0, p.stderr
    assert "fastest:" in p.stdout and (tmp_path / "out" / "work_precision.png").exists()


def test_method_best_settings_and_their_overrides():
    # baraff_witkin's measured best (BaraffWitkinRow, peers/baraff_witkin.cc): Blender's CG
    # tolerance 1e-2 and J_alpha of tension and mass only, unless the call
    # names its own; the run reports what it used.
    r = clothbench.run("swinging_sheet", "baraff_witkin", h=0.01, t_end=0.05)
    assert r["status"] == "ok" and r["cg_tolerance"] == 1e-2 and r["tangent_terms"] == "tension"
    r = clothbench.run("swinging_sheet", "baraff_witkin", h=0.01, t_end=0.05, cg_tolerance=1e-6, tangent_terms="all")
    assert r["status"] == "ok" and r["cg_tolerance"] == 1e-6 and r["tangent_terms"] == "all"
    r = clothbench.run("swinging_sheet", "bdf2/newton", h=0.01, t_end=0.05)
    assert r["cg_tolerance"] == 1e-6 and r["tangent_terms"] == "all"  # the scene's
    assert clothbench.run("swinging_sheet", "sbdf2", h=0.01, t_end=0.05)["tangent_terms"] == ""
    with pytest.raises(ValueError, match="tangent_terms"):
        clothbench.run("swinging_sheet", "baraff_witkin", h=0.01, tangent_terms="some")


def test_progress_callback_reports_and_can_stop_a_run():
    seen = []
    r = clothbench.run("swinging_sheet", "sbdf2", h=0.001, t_end=0.2, progress=lambda t, t_end: seen.append((t, t_end)))
    assert r["status"] == "ok"
    # Called at least at t_end (the 0.2 s throttle may skip the others), never past it.
    assert seen and seen[-1] == (pytest.approx(0.2), 0.2) and all(t <= 0.2 + 1e-12 for t, _ in seen)

    def stop(t, t_end):
        raise KeyboardInterrupt("enough")

    with pytest.raises(KeyboardInterrupt, match="enough"):
        clothbench.run("swinging_sheet", "sbdf2", h=0.001, t_end=0.2, progress=stop)


def test_result_file_written_from_python_matches_the_command_line(tmp_path):
    # The same rows and reference through bench_integrators and through
    # run/reference/write_results: the same records (counts, errors, orders,
    # energies to the bit; times differ), read back by read_results.
    cli = tmp_path / "cli.h5"
    subprocess.run([os.environ["CLOTHBENCH_BENCH_INTEGRATORS"], "--integrators", "sbdf2", "--h", "0.01,0.005",
                    "--out", str(cli), "--quiet"], check=True, stdout=subprocess.DEVNULL)
    scene = clothbench.load_scene("swinging_sheet")
    ref = clothbench.reference(scene)
    runs = [clothbench.run(scene, "sbdf2", h=h, reference=ref) for h in (0.01, 0.005)]
    assert runs[0]["error_final_m"] == clothbench.error_rms(runs[0]["positions"][-1], ref["positions"][-1])
    py_file = tmp_path / "py.h5"
    clothbench.write_results(str(py_file), scene, runs, reference=ref)
    a, b = clothbench.read_results(str(cli)), clothbench.read_results(str(py_file))
    assert a["schema"] == b["schema"] and a["scene"]["name"] == b["scene"]["name"] == "swinging_sheet"
    assert b["reference"]["integrator"] == a["reference"]["integrator"] == "cvode"
    assert len(a["runs"]) == len(b["runs"]) == 2
    for x, y in zip(a["runs"], b["runs"]):
        for key in ("id", "label", "steps", "cg_iterations", "preconditioner", "error_final_m", "error_max_m",
                    "observed_order", "energy_rate_W"):
            assert x[key] == y[key], key
    assert b["runs"][1]["observed_order"] is not None and b["work_precision"]["labels"] == ["sbdf2"]
    with pytest.raises(ValueError, match="runs"):
        clothbench.write_results(str(tmp_path / "bad.h5"), scene, [{"id": "x"}])


def test_python_records_list_the_files_fields(tmp_path):
    # The scene record, the energy series and the step history each come
    # from one field list (results/run_table.h SceneRecordFields,
    # results/metrics.h EnergySeriesFields, results/result_file.h
    # StepRecordFields): what run() and read_results() show is what the file
    # stores, key for key and value for value.
    scene = clothbench.load_scene("round_table", {"t_end": 0.3})
    r = clothbench.run(scene, "sbdf2", h=0.01, repeat=1)
    out = tmp_path / "fields.h5"
    clothbench.write_results(str(out), scene, [r])
    back = clothbench.read_results(str(out))
    with h5py.File(out, "r") as f:
        attrs = {k: f["scene"].attrs[k] for k in f["scene"].attrs}
        g = f["runs"][r["id"]]
        energy = {k: g["energy"][k][()] for k in g["energy"]}
        steps = g["step_stats"][()]
        stored_status = g.attrs["status"]
    keys = {k[len("solver_"):] if k.startswith("solver_") else k for k in attrs}
    assert set(back["scene"]) == keys
    for k, v in attrs.items():
        v = v.decode() if isinstance(v, bytes) else v
        assert back["scene"][k[len("solver_"):] if k.startswith("solver_") else k] == v, k
    assert set(r["energy"]) == set(energy) and "contact_work_holding" in energy  # sbdf2 tracks its contact work
    for k, v in energy.items():
        assert np.array_equal(np.asarray(r["energy"][k]), v), k
    assert r["step_stats"].dtype.names == steps.dtype.names
    assert np.array_equal(r["step_stats"], steps.astype(r["step_stats"].dtype))
    status = stored_status.decode() if isinstance(stored_status, bytes) else stored_status
    assert r["status"] == back["runs"][0]["status"] == status == "ok"
    assert r["step_kind"] == back["runs"][0]["step_kind"] == "fixed_step"


def test_run_repeats_its_timing():
    # Three timings of one run: the least is solver_time_s, with the median
    # and the largest (each later timing reproduced the end state bit for
    # bit, else run() raises); the record carries the settings it ran with.
    r = clothbench.run("swinging_sheet", "sbdf2", h=0.01, t_end=0.1, repeat=3)
    assert r["repeats"] == 3
    assert 0 < r["solver_time_s"] <= r["solver_time_s_median"] <= r["solver_time_s_max"]
    assert r["step_control"] == "fixed" and r["threads"] >= 1
    # Without repeat: DiffEqDevTools' rule, 3 timings for a run under 2 s,
    # unless the time budget is spent; one with a zero budget.
    assert clothbench.run("swinging_sheet", "sbdf2", h=0.01, t_end=0.1)["repeats"] == 3
    assert clothbench.run("swinging_sheet", "sbdf2", h=0.01, t_end=0.1, time_budget=0.0)["repeats"] == 1
    with pytest.raises(ValueError):
        clothbench.run("swinging_sheet", "sbdf2", h=0.01, repeat=0)


def test_scene_error_control_makes_an_error_row():
    # On a scene under error control, "sbdf2" is sbdf2/error at the scene's
    # rtol, as on the command line.
    scene = clothbench.load_scene("swinging_sheet", {"solver.step_control": "error", "solver.rtol": 1e-3,
                                                     "t_end": 0.1})
    r = clothbench.run(scene, "sbdf2", repeat=1)
    assert r["label"] == "sbdf2/error" and r["step_kind"] == "adaptive" and r["rtol"] == 1e-3
    assert r["step_control"] == "error"


def test_contact_phases_summarises_step_stats(tmp_path):
    # scripts/contact_phases, which prints docs/notes/performance.md's contact
    # tables, on the 400-particle round table: its rows must be the file's
    # step_stats, split into the phases its docstring names. The file has no
    # frames (--frames none): the particle count comes from /scene.
    out = tmp_path / "rt.h5"
    subprocess.run([os.environ["CLOTHBENCH_BENCH_INTEGRATORS"], "--scene", "round_table", "--integrators", "sbdf2",
                    "--h", "0.01", "--t-end", "0.6", "--reference", "none", "--frames", "none", "--repeat", "1",
                    "--preconditioner", "amg", "--out", str(out), "--quiet"], check=True, stdout=subprocess.DEVNULL)
    script = os.path.join(os.path.dirname(__file__), "..", "scripts", "contact_phases")
    p = subprocess.run(["/usr/bin/python3", script, str(out)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    rows = {cells[3]: cells for cells in (line.split("|") for line in p.stdout.splitlines()[2:])}
    with h5py.File(out, "r") as f:
        steps = f["runs/sbdf2_h0.01/step_stats"][()]
        assert "positions" not in f["runs/sbdf2_h0.01"]
        n = int(f["scene"].attrs["n_particles"])
    steps = steps[steps["status"] == 0]
    first = int(np.nonzero(steps["colliding"] >= 0.02 * n)[0][0])
    impact = steps[first:first + 20]
    resting = steps[steps["t"] > steps["t"][-1] - 0.3 + 1e-9]
    full = steps[first + 20:][steps["colliding"][first + 20:] >= 0.3 * n]
    assert set(rows) == {" free ", " impact ", " resting "} | ({" full "} if len(full) else set())
    if len(full):
        assert int(rows[" full "][4]) == len(full)
    assert int(rows[" free "][4]) == min(first, 12) - 2
    assert int(rows[" impact "][4]) == len(impact) and int(rows[" resting "][4]) == len(resting)
    assert float(rows[" impact "][7]) == pytest.approx(np.mean(impact["cg_iterations"]), abs=0.05)
    assert float(rows[" resting "][7]) == pytest.approx(np.mean(resting["cg_iterations"]), abs=0.05)
    p = subprocess.run(["/usr/bin/python3", script, "--resting", "0", str(out)], capture_output=True, text=True)
    assert p.returncode != 0 and "--resting" in p.stderr
    p = subprocess.run(["/usr/bin/python3", script, "--full", "0", str(out)], capture_output=True, text=True)
    assert p.returncode != 0 and "--full" in p.stderr


@pytest.mark.parametrize("with_callback", [False, True])
def test_ctrl_c_stops_a_run_within_0_2_s(with_callback):
    # SIGINT from another thread 0.3 s into a run of 2·10^4 small steps
    # (about 0.1 ms each at 400 particles, 1.8 s in all): the module checks for a pending
    # signal every 50 ms between steps, with or without a progress
    # callback, so KeyboardInterrupt reaches the caller within 0.2 s of the
    # signal (0.05 s of checking interval, one step, and the unwinding).
    import signal
    import threading
    import time
    sent = []

    def interrupt():
        time.sleep(0.3)
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    progress = (lambda t, t_end: None) if with_callback else None
    threading.Thread(target=interrupt, daemon=True).start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        clothbench.run("swinging_sheet", "sbdf2", h=5e-5, progress=progress, repeat=1)
    stopped = time.monotonic()
    assert sent, "the run ended before the signal: make it longer"
    assert stopped - sent[0] < 0.2, f"{stopped - sent[0]:.3f} s from SIGINT to KeyboardInterrupt"
    assert stopped - start < 1.0


def test_run_from_several_threads_is_bit_identical_to_serial():
    # run() may be called from several threads: the calls compute one at a
    # time (a process-wide lock), each with its own progress callback, and
    # give the serial results bit for bit.
    import threading
    serial = {m: clothbench.run("swinging_sheet", m, h=0.01, t_end=0.2, repeat=1) for m in ("sbdf2", "bdf2/newton")}
    results, calls, errors = {}, {"sbdf2": [], "bdf2/newton": []}, []

    def work(m):
        try:
            results[m] = clothbench.run("swinging_sheet", m, h=0.01, t_end=0.2, repeat=1,
                                        progress=lambda t, t_end: calls[m].append(t))
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(m,)) for m in serial for _ in range(1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    for m, r in serial.items():
        assert np.array_equal(results[m]["positions"], r["positions"]), m
        assert calls[m] and calls[m][-1] == pytest.approx(0.2), m


def test_write_results_respects_the_lock_and_special_files(tmp_path):
    import fcntl
    scene = clothbench.load_scene("swinging_sheet", {"t_end": 0.05})
    run = clothbench.run(scene, "sbdf2", h=0.01)
    out = tmp_path / "r.h5"
    # Another process' lock on <out>.lock (bench_integrators holds it while it computes).
    holder = subprocess.Popen(["/usr/bin/python3", "-c",
                               "import fcntl, sys, time; f = open(sys.argv[1], 'w'); fcntl.flock(f, fcntl.LOCK_EX); "
                               "f.write('4242'); f.flush(); print('locked', flush=True); time.sleep(30)",
                               str(out) + ".lock"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(ValueError, match="^path: .* is being written by process"):
            clothbench.write_results(str(out), scene, [run])
        assert not out.exists()
    finally:
        holder.kill()
        holder.wait()
    # A folder, a FIFO and a device are never replaced by a regular file.
    fifo = tmp_path / "fifo.h5"
    os.mkfifo(fifo)
    folder = tmp_path / "folder.h5"
    folder.mkdir()
    specials = [fifo, folder]
    if os.geteuid() == 0:  # a character device like /dev/null, made in the scratch folder
        import stat
        device = tmp_path / "device.h5"
        os.mknod(device, stat.S_IFCHR | 0o600, os.makedev(1, 3))
        specials.append(device)
    for path in specials:
        with pytest.raises(ValueError, match="^path: .* is a (FIFO|folder|device); an output is written only over a regular file"):
            clothbench.write_results(str(path), scene, [run])
    assert fifo.is_fifo() and folder.is_dir()
    if os.geteuid() == 0:
        assert device.is_char_device()
    clothbench.write_results(str(out), scene, [run])
    assert out.is_file() and not (tmp_path / "r.h5.tmp").exists() and not (tmp_path / "r.h5.lock").exists()


def test_read_results_refuses_a_file_that_crashes_hdf5():
    # verify/fuzz/result_regressions/hdf5_crash_signed.bin: its integrity
    # block matches, yet HDF5 1.10 crashes (SIGSEGV) reading its damaged
    # attribute headers. read_results reads it in a child process first
    # (whose listing of the links already finds it damaged): ValueError
    # naming the file, and this interpreter lives on.
    path = os.path.join(os.path.dirname(__file__), "..", "verify", "fuzz", "result_regressions",
                        "hdf5_crash_signed.bin")
    with pytest.raises(ValueError, match="hdf5_crash_signed.bin: .*damaged"):
        clothbench.read_results(path)


def test_write_results_defaults_to_the_metric_bench_integrators_uses(tmp_path):
    # Without error_metric the file's metric is the command line's default:
    # l2 on a scene with obstacles (contact events are not smooth), final
    # without; a named metric is kept.
    for name, expected in (("swinging_box", "l2"), ("swinging_sheet", "final")):
        scene = clothbench.load_scene(name, {"t_end": 0.05})
        run = clothbench.run(scene, "sbdf2", h=0.01)
        out = tmp_path / (name + ".h5")
        clothbench.write_results(str(out), scene, [run], frames="none")
        named = tmp_path / (name + "_max.h5")
        clothbench.write_results(str(named), scene, [run], frames="none", error_metric="max")
        with h5py.File(out) as f, h5py.File(named) as g:
            assert f.attrs["error_metric"] in (expected, expected.encode())
            assert g.attrs["error_metric"] in ("max", b"max")


def test_obstacle_distances_are_the_models_queries():
    # scenes/sphere_drape.toml: a sphere of radius 0.25 m about (0, 0, 0.5).
    # A point 1 m above the centre lies 0.75 m outside, one 0.1 m above it
    # 0.15 m inside, both along +z (exact but for round-off: 1e-12).
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    scene = clothbench.load_scene(os.path.join(root, "scenes", "sphere_drape.toml"))
    x = np.zeros((1, 2, 3))
    x[0, 0] = [0.0, 0.0, 1.5]
    x[0, 1] = [0.0, 0.0, 0.6]
    near = clothbench.obstacle_distances(scene, [0.0], x)
    assert near["distance"][0] == pytest.approx([0.75, -0.15], abs=1e-12)
    assert near["direction"][0, :, 2] == pytest.approx([1.0, 1.0], abs=1e-12)
    assert list(near["obstacle"][0]) == [0, 0]
    with pytest.raises(ValueError, match="times"):
        clothbench.obstacle_distances(scene, [0.0, 1.0], x)
    with pytest.raises(ValueError, match="positions"):
        clothbench.obstacle_distances(scene, [0.0], np.zeros((1, 2, 2)))
    with pytest.raises(ValueError, match="no obstacle"):
        clothbench.obstacle_distances(clothbench.load_scene("swinging_sheet"), [0.0], x)


def test_self_contact_switch_counts_and_removes_the_crossings():
    # fold_over_rod to t = 0.6 s: its halves swing through each other at
    # about 0.45 s without self-contact (230 crossing pairs at 0.5 s).
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    scene = os.path.join(root, "scenes", "fold_over_rod.toml")
    off = clothbench.run(scene, "sbdf2", h=0.005, t_end=0.6, self_contact="off")
    on = clothbench.run(scene, "sbdf2", h=0.005, t_end=0.6)
    assert off["collision_self"] == "off" and on["collision_self"] == "on"
    assert off["status"] == "ok" and max(off["crossing_pairs"]) > 50 and "self_contact" not in off
    assert on["status"] == "ok" and max(on["crossing_pairs"]) == 0
    assert len(on["crossing_pairs"]) == len(on["times"])
    assert on["self_contact"]["collisions"] + on["self_contact"]["repulsions"] > 0
    with pytest.raises(ValueError, match="self_contact"):
        clothbench.run(scene, "sbdf2", h=0.005, t_end=0.1, self_contact="maybe")
    # XPBD and VBD have their own (constraints in the substeps, a penalty
    # within bounds), PD its impulses in the global step with the response
    # as the fail-safe; the SUNDIALS rows take the response at every
    # internal step's end and restart. (PD at 4 iterations per 5 ms step keeps the halves apart to
    # 0.6 s; at 16 they meet and its pairs hold impulses.)
    xpbd = clothbench.run(scene, "xpbd", h=0.005, substeps=16, t_end=0.6)
    assert xpbd["status"] == "ok" and max(xpbd["crossing_pairs"]) == 0
    assert xpbd["self_contact"]["projections"] > 0
    vbd = clothbench.run(scene, "vbd", h=0.005, iterations=1, t_end=0.6)
    assert vbd["status"] == "ok" and max(vbd["crossing_pairs"]) == 0
    pd = clothbench.run(scene, "pd", h=0.005, iterations=16, t_end=0.6)
    assert pd["status"] == "ok" and max(pd["crossing_pairs"]) == 0
    assert pd["self_contact"]["pair_impulses"] > 0
    cvode = clothbench.run(scene, "cvode", rtol=1e-3, t_end=0.6)
    assert cvode["status"] == "ok" and max(cvode["crossing_pairs"]) == 0
    assert cvode["self_contact"]["repulsions"] > 0


def test_twisted_sheet_moves_its_edge_and_refuses_the_sundials_rows():
    # twisted_sheet to t = 1 s (one whole turn of its u1 edge): without
    # self-contact SBDF(2)'s strip crosses itself from t = 0.68 s (348
    # pairs at most to 2 s); with it no frame crosses. The moving edge's
    # first particle, (0.3, -0.075, 0.5) m at rest, is at the motion's pose:
    # a quarter turn about x through (0.3, 0, 0.5) and 0.025 m along -x at
    # t = 0.25 s (round-off of the pose, 1e-12 m).
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    scene = os.path.join(root, "scenes", "twisted_sheet.toml")
    off = clothbench.run(scene, "sbdf2", h=0.005, t_end=1.0, self_contact="off")
    on = clothbench.run(scene, "sbdf2", h=0.005, t_end=1.0)
    assert off["status"] == "ok" and max(off["crossing_pairs"]) > 50
    assert on["status"] == "ok" and max(on["crossing_pairs"]) == 0
    times = list(on["times"])
    k = min(range(len(times)), key=lambda i: abs(times[i] - 0.25))
    corner = on["positions"][k][39]  # particle (nu - 1, 0)
    assert abs(times[k] - 0.25) < 1e-12
    assert max(abs(a - b) for a, b in zip(corner, (0.275, 0.0, 0.425))) < 1e-12
    assert clothbench.run(scene, "cvode", rtol=1e-4, t_end=0.1)["status"] == "unsupported_scene"


def test_a_sewn_garment_runs_as_on_the_command_line(tmp_path):
    # scenes/sewn_panels.toml: two panels sewn around a cylinder (its
    # sewing phase runs once, before the row). The module and
    # bench_integrators run the same harness on the same sewn start, so
    # every stored frame is equal to the bit; the seams stay closed.
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    scene = os.path.join(root, "scenes", "sewn_panels.toml")
    out = tmp_path / "cli.h5"
    subprocess.run([os.environ["CLOTHBENCH_BENCH_INTEGRATORS"], "--scene", scene, "--integrators", "sbdf2",
                    "--h", "0.005", "--t-end", "0.2", "--reference", "none", "--frames", "all", "--out", str(out),
                    "--quiet"], check=True, stdout=subprocess.DEVNULL)
    r = clothbench.run(scene, "sbdf2", h=0.005, t_end=0.2)
    assert r["status"] == "ok" and max(r["crossing_pairs"]) == 0
    assert r["positions"].shape == (5, 160, 3)  # 2 x 11 x 8 samples, 2 x 8 merged
    with h5py.File(out) as f:
        assert np.array_equal(f["runs/sbdf2_h0.005/positions"][:], r["positions"])
        assert np.array_equal(f["scene/sewn_start"][:], r["positions"][0])
    # A selection without its pattern is refused on a garment, as on the
    # command line.
    with pytest.raises(ValueError, match="pattern"):
        clothbench.run(clothbench.load_scene(scene, {"constraints.fixed": ["edge:v0"]}), "sbdf2", h=0.005,
                       t_end=0.01)
