"""The report page and the outputs beside it, against planted inputs (run by ctest as python.pytest).

Each test plants what a hostile or careless user would: markup in a stored
number or name of a result file signed again by hand, a result file too
large for a page, a stored link to another site, concurrent writers of one
page, and outputs that name another command's lock, journal or page.
scripts/report must refuse bad input before reading it (exit 2, one line),
escape every stored string, stay within its caps, and never let a stored
value or an output option replace a file it does not own.
"""
import importlib.machinery
import importlib.util
import os
import subprocess

import pytest

import clothbench
from test_outputs import TINY, resign  # the tiny scene and the forger's integrity block

BIN = os.path.dirname(os.environ["CLOTHBENCH_BENCH_INTEGRATORS"])
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
REPORT = os.path.join(ROOT, "scripts", "report")
ENV = dict(os.environ, CLOTHBENCH_PYTHON_DIR=os.path.dirname(os.path.abspath(clothbench.__file__)))


def bench(args, cwd):
    return subprocess.run([os.path.join(BIN, "bench_integrators")] + args, cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def report(args, cwd):
    return subprocess.run(["/usr/bin/python3", REPORT] + args, cwd=cwd, capture_output=True, text=True, timeout=300,
                          env=ENV)


def one_line_refusal(p, needle):
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert needle in lines[0], lines[0]


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """A small result file: sbdf2 and cvode on the tiny scene, with the reference."""
    d = tmp_path_factory.mktemp("report")
    (d / "tiny.toml").write_text(TINY)
    p = bench(["--scene", "tiny.toml", "--integrators", "sbdf2,cvode", "--h", "0.01", "--rtols", "1e-3", "--repeat",
               "1", "--out", "r.h5", "--quiet"], d)
    assert p.returncode == 0, p.stderr
    return d / "r.h5"


def edited(stored, tmp_path, edit):
    import h5py
    import shutil
    path = tmp_path / "edited.h5"
    shutil.copy(stored, path)
    with h5py.File(path, "r+") as f:
        edit(f)
    resign(path)
    return path


def test_markup_in_a_stored_number_is_refused_before_any_page(stored, tmp_path):
    markup = '<meta http-equiv="refresh" content="0;url=file:///etc/passwd">'

    def plant(f):
        f["scene"].attrs["n_particles"] = markup
        f["scene"].attrs["n_fixed"] = markup
    path = edited(stored, tmp_path, plant)
    one_line_refusal(report([str(path)], tmp_path), "n_particles")
    assert not (tmp_path / "edited.html").exists()


def test_stored_strings_are_escaped_and_drawn_as_plain_text(stored, tmp_path):
    name = '<meta http-equiv="refresh" content="0;url=file:///etc/passwd"><style>body{display:none}</style>$USER_$HOST'

    def plant(f):
        f["scene"].attrs["name"] = name
    path = edited(stored, tmp_path, plant)
    p = report([str(path)], tmp_path)
    assert p.returncode == 0, p.stderr  # "$USER_$HOST" is text, not mathtext
    page = (tmp_path / "edited.html").read_text()
    # As text (escaped in the HTML, and in the plots' SVG text), never as markup.
    assert '<meta http-equiv="refresh"' not in page
    assert "<style>body{display:none}" not in page
    assert "&lt;meta http-equiv=&quot;refresh&quot;" in page


def test_the_page_shows_at_most_its_cap_of_runs(stored, tmp_path):
    def plant(f):
        first = next(iter(f["runs"]))
        for k in range(600):
            f.copy(f["runs"][first], f"runs/x{k:04d}")
    path = edited(stored, tmp_path, plant)
    p = report([str(path)], tmp_path)
    assert p.returncode == 0, p.stderr
    page = (tmp_path / "edited.html").read_text()
    assert "shows the first 500" in page
    assert page.count("&#x27; rerun &#x27;") == 500  # one command a shown run
    assert "x0599" not in page


def test_a_stability_map_beyond_the_page_budget_is_refused_before_reading(stored, tmp_path):
    import numpy as np

    def plant(f):
        g = f.create_group("stress")
        g["stiffness"] = np.linspace(1.0, 2.0, 300)
        g["h"] = np.linspace(0.001, 0.01, 300)
        g.create_dataset("tiny/sbdf2/outcome", data=np.zeros((300, 300), dtype=np.int32), compression="gzip")
    path = edited(stored, tmp_path, plant)
    one_line_refusal(report([str(path)], tmp_path), "stability map of 300×300 cells")


def test_a_stored_result_file_entry_links_only_to_the_sweeps_own_page(tmp_path):
    loader = importlib.machinery.SourceFileLoader("report_sections", os.path.join(ROOT, "scripts",
                                                                                   "report_sections.py"))
    spec = importlib.util.spec_from_loader("report_sections", loader)
    sections = importlib.util.module_from_spec(spec)
    loader.exec_module(sections)
    verdict = tmp_path / "v.h5"
    (tmp_path / "https:" / "evil.example").mkdir(parents=True)
    (tmp_path / "https:" / "evil.example" / "x.html").write_text("planted")
    assert sections.size_page_link(str(verdict), "https://evil.example/x.h5", 400) == ""
    (tmp_path / "other.html").write_text("planted")
    assert sections.size_page_link(str(verdict), "other.h5", 400) == ""
    (tmp_path / "v.n400.html").write_text("the size's page")
    link = sections.size_page_link(str(verdict), "v.n400.h5", 400)
    assert 'href="./v.n400.html"' in link


def test_concurrent_writers_of_one_page_all_succeed(stored, tmp_path):
    page = tmp_path / "page.html"
    procs = [subprocess.Popen(["/usr/bin/python3", REPORT, str(stored), "--out", str(page)], env=ENV,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(4)]
    for p in procs:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
    assert page.read_text().startswith("<!-- clothbench report -->")
    assert not [n for n in os.listdir(tmp_path) if n.endswith(".tmp")]


@pytest.mark.parametrize("out,needle", [("/proc/x.html", "/proc/x.html"), ("a.h5.lock", "lock file"),
                                        ("j.h5.journal/p.html", "inside the journal")])
def test_report_refuses_outputs_it_must_not_write(stored, tmp_path, out, needle):
    one_line_refusal(report([str(stored), "--out", out], tmp_path), needle)


def test_another_commands_lock_or_journal_is_refused_as_an_output(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "a.h5.journal").mkdir()
    (tmp_path / "a.h5.journal" / "key").write_text("a running sweep's key\n")
    for out, needle in [("a.h5.lock", "lock file"), ("a.h5.journal/key", "inside the journal"),
                        ("a.h5.journal", "journal"), ("b.h5.tmp", "temporary file")]:
        p = bench(["--scene", "tiny.toml", "--integrators", "sbdf2", "--h", "0.01", "--reference", "none", "--out",
                   out, "--quiet"], tmp_path)
        one_line_refusal(p, needle)
    assert (tmp_path / "a.h5.journal" / "key").read_text() == "a running sweep's key\n"


def test_series_naming_the_report_page_is_refused_before_computing(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "r.html").write_text("<!-- clothbench report -->\nan earlier page\n")
    p = bench(["--scene", "tiny.toml", "--integrators", "sbdf2", "--h", "0.01", "--reference", "none", "--out", "r.h5",
               "--report", "--series", "r.html", "--quiet"], tmp_path)
    one_line_refusal(p, "--series")
    assert (tmp_path / "r.html").read_text() == "<!-- clothbench report -->\nan earlier page\n"
    assert not (tmp_path / "r.h5").exists()


def test_a_report_named_like_an_option_and_a_dollar_name_are_written(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY.replace('name = "tiny"', 'name = "sheet_$USER_$HOST"'))
    p = bench(["--scene", "tiny.toml", "--integrators", "sbdf2", "--h", "0.01", "--reference", "none", "--out",
               "-x.h5", "--report", "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "-x.html").read_text().startswith("<!-- clothbench report -->")


def test_the_scene_picture_draws_a_moving_body_where_it_was(tmp_path):
    # mesh_sequence_drape's sphere swells and rises: the picture has four
    # panels through the motion, each with the body at its own time (the
    # stored surface nearest the panel's time differs between panels).
    scene = os.path.join(ROOT, "scenes", "mesh_sequence_drape.toml")
    p = bench(["--scene", scene, "--integrators", "sbdf2", "--h", "0.01", "--t-end", "0.3", "--reference", "none",
               "--repeat", "1", "--out", "r.h5", "--quiet"], tmp_path)
    assert p.returncode == 0, p.stderr
    r = report([str(tmp_path / "r.h5")], tmp_path)
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "r.html").read_text()
    scene_figure = page[page.index('id="fig-scene"'):]
    scene_figure = scene_figure[:scene_figure.index("</figure>")]
    for t in ("t = 0 s", "t = 0.1 s", "t = 0.2 s", "t = 0.3 s"):
        assert t in scene_figure, t
    import h5py
    with h5py.File(tmp_path / "r.h5", "r") as f:
        body = f["scene/obstacles/0/positions"][:]
        assert f["scene/obstacles/0/times"].shape == (31,)
    assert abs(body[-1] - body[0]).max() > 0.01  # it moved: the panels draw different surfaces
