"""The sections of a clothbench report page (scripts/report): tables as
plain HTML, figures from scripts/plot as inline SVG.

Each page kind returns its sections as (id, title, HTML) and the fastest
methods it names: bench_page (a bench_integrators file), sizes_page (a
--sizes verdict), stress_page (stress_stability). Loaded by scripts/report,
which sets P (scripts/plot as a module) before use.
"""
import html
import io
import os
import re
import urllib.parse

import matplotlib.pyplot as plt
import numpy as np

P = None  # scripts/plot, set by scripts/report (load_sections)


def attr(g, key, default=None):
    return P.attr(g, key, default)


def esc(v):
    return html.escape(str(v), quote=True)


def num(g, key, kind=float):
    """Attribute `key` of `g` as a finite number of `kind` (int or float):
    a stored string, however it looks, is never written into the page as a
    number. ValueError naming the attribute otherwise."""
    v = g.attrs.get(key)
    if isinstance(v, np.ndarray) and v.size == 1:
        v = v.ravel()[0]
    ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
    if not ok or not np.isfinite(v) or (kind is int and float(v) != int(v)):
        raise ValueError(f"{g.name}@{key}: {'an integer' if kind is int else 'a finite number'} expected, "
                         f"found {type(v).__name__}")
    return kind(v)


# The page's caps: what any file, however large, is summarised to.
MAX_RUNS = 500             # runs in the tables and the plots; the rest are counted, not shown
MAX_POINTS = 20000         # points of one plotted line (evenly thinned beyond)
MAX_LINES = 1000           # lines of a list (why each sweep stopped)
MAX_SIZES = 50             # sizes of a --sizes verdict
MAX_OBSTACLES = 50         # obstacles drawn in the scene's picture


def thin(n):
    """The stride that keeps at most MAX_POINTS of n points."""
    return max(1, -(-n // MAX_POINTS))


def fmt(v):
    if isinstance(v, bytes):
        v = v.decode()
    if isinstance(v, (float, np.floating)):
        return f"{v:.4g}"
    if isinstance(v, np.ndarray):
        return ", ".join(fmt(x) for x in v.ravel())
    return str(v)


def table(header, rows, cls="", caption=""):
    out = [f'<table class="{cls}">' if cls else "<table>"]
    if caption:
        out.append(f"<caption>{esc(caption)}</caption>")
    out.append("<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr></thead><tbody>")
    for r in rows:
        out.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in r) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


class Figures:
    """A sink for scripts/plot: each figure becomes inline SVG."""

    def __init__(self):
        self.svg = {}

    def __call__(self, fig, name):
        buf = io.StringIO()
        fig.savefig(buf, format="svg", bbox_inches="tight", dpi=110, metadata={"Date": None, "Creator": None})
        text = buf.getvalue()
        text = text[text.index("<svg"):]  # drop the XML prolog and DOCTYPE
        text = re.sub(r"<metadata>.*?</metadata>\s*", "", text, flags=re.S)  # RDF: names, not requests
        # Each figure's ids (glyphs, clip paths) in a namespace of their own.
        prefix = re.sub(r"[^A-Za-z0-9]", "_", name) + "_"
        text = re.sub(r'id="([^"]+)"', lambda m: f'id="{prefix}{m.group(1)}"', text)
        text = re.sub(r"url\(#([^)]+)\)", lambda m: f"url(#{prefix}{m.group(1)})", text)
        text = re.sub(r'((?:xlink:)?href)="#([^"]+)"', lambda m: f'{m.group(1)}="#{prefix}{m.group(2)}"', text)
        self.svg[name] = f'<figure class="plot" id="fig-{esc(name)}">{text}</figure>'
        plt.close(fig)

    def take(self, name):
        return self.svg.pop(name, "")


# ---------------------------------------------------------------- the scene
def cloth_frames(f):
    """(label, positions dataset, times) of the reference or the first run
    that stores frames; `times` has one entry per stored frame."""
    groups = ([("reference", f["reference"])] if "reference" in f else []) + list(f["runs"].items())
    for name, g in groups:
        if "positions" in g and len(g["positions"]) >= 2:
            return name, g["positions"], g["times"][: len(g["positions"])]
        if "positions_ends" in g and len(g["positions_ends"]) >= 2:
            return name, g["positions_ends"], np.array([0.0, attr(f["scene"], "t_end")])
    return None


def moving_body(f):
    """Whether a stored obstacle deforms (its surface has stored times)."""
    return any("positions" in o for o in f["scene"].get("obstacles", {}).values())


def draw_obstacles(ax, f, spec, lo, hi, t=0.0):
    """The scene's obstacles; a deforming one at its stored time nearest t [s]."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    stored = f["scene"].get("obstacles", {})
    for k, o in enumerate(spec.get("obstacle", [])[:MAX_OBSTACLES]):
        if not isinstance(o, dict):
            continue
        style = dict(color="0.55", linewidth=0.6, alpha=0.7)
        if str(k) in stored and "triangles" in stored[str(k)]:
            ov, ot = stored[str(k)]["vertices"][:], stored[str(k)]["triangles"][:]
            body = "positions" in stored[str(k)]  # a deforming body, drawn darker
            if body:
                ov = stored[str(k)]["positions"][int(np.argmin(np.abs(stored[str(k)]["times"][:] - t)))]
            if len(ot) > 20000:  # a picture, not a render: every n-th triangle
                ot = ot[:: len(ot) // 20000 + 1]
            mesh = Poly3DCollection([ov[i] for i in ot], facecolor="tan" if body else "0.75", edgecolor="none",
                                    alpha=0.8 if body else 0.3)
            mesh.set_rasterized(len(ot) > 2000)
            ax.add_collection3d(mesh)
            continue
        c = np.array(o.get("center", [0.0, 0.0, 0.0]), dtype=float)
        t = o.get("type")
        if t == "sphere":
            r = float(o.get("radius", 0.3))
            u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13))
            ax.plot_wireframe(c[0] + r * np.cos(u) * np.sin(v), c[1] + r * np.sin(u) * np.sin(v),
                              c[2] + r * np.cos(v), **style)
        elif t == "cylinder":
            r, hgt = float(o.get("radius", 0.3)), float(o.get("height", 0.7))
            u, z = np.meshgrid(np.linspace(0, 2 * np.pi, 33), np.linspace(c[2] - hgt, c[2], 5))
            ax.plot_wireframe(c[0] + r * np.cos(u), c[1] + r * np.sin(u), z, **style)
        elif t == "box":
            s = 0.5 * np.array(o.get("size", [1.0, 1.0, 1.0]), dtype=float)
            for a in range(3):
                b, d = [i for i in range(3) if i != a]
                for sb in (-1, 1):
                    for sd in (-1, 1):
                        p, q = c.copy(), c.copy()
                        p[a], q[a] = c[a] - s[a], c[a] + s[a]
                        p[b] = q[b] = c[b] + sb * s[b]
                        p[d] = q[d] = c[d] + sd * s[d]
                        ax.plot(*zip(p, q), **style)
        elif t == "plane":
            n = np.array(o.get("normal", [0.0, 0.0, 1.0]), dtype=float)
            n /= np.linalg.norm(n)
            e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(n, e1)
            r = 0.6 * float(np.max(hi - lo))
            corners = [c + r * (a * e1 + b * e2) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            ax.add_collection3d(Poly3DCollection([corners], facecolor="0.8", edgecolor="0.5", alpha=0.3))


def scene_figure(f, spec, sink):
    got = cloth_frames(f)
    if got is None or "faces" not in f["scene"]:
        return ""
    name, frames, times = got
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    quads = f["scene"]["faces"][:]
    if len(quads) > 40000:  # a picture: a coarser set of the grid's quads
        quads = quads[:: len(quads) // 40000 + 1]
    # A moving body: four times through the motion; otherwise the ends.
    panels = [0, len(times) - 1]
    if moving_body(f) and len(times) > 3:
        panels = sorted({int(round(q * (len(times) - 1))) for q in (0.0, 1 / 3, 2 / 3, 1.0)})
    shown = [(frames[i], float(times[i])) for i in panels]
    pts = np.vstack([x for x, _ in shown])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    rows = (len(shown) + 1) // 2
    fig = plt.figure(figsize=(10, 4.8 * rows))
    for panel, (x, t) in enumerate(shown):
        ax = fig.add_subplot(rows, 2, panel + 1, projection="3d")
        draw_obstacles(ax, f, spec, lo, hi, t)
        cloth = Poly3DCollection([x[q] for q in quads], facecolor="tab:blue", edgecolor="k",
                                 linewidth=0.15 if len(quads) > 2000 else 0.4, alpha=0.35 if len(panels) > 2 else 0.6)
        # Above a few thousand quads the cloth is drawn as an image inside
        # the SVG (a data: URI, no request): 40,000 vector quads are 15 MB.
        cloth.set_rasterized(len(quads) > 2000)
        ax.add_collection3d(cloth)
        pad = 0.1 * max(float(np.max(hi - lo)), 1e-3)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_zlim(lo[2] - pad, hi[2] + pad)
        ax.set_box_aspect(np.maximum(hi - lo + 2 * pad, 1e-3))
        ax.set_title(f"t = {t:.3g} s ({name})", fontsize=9)
        ax.view_init(elev=22, azim=-60)
        ax.tick_params(labelsize=6)
    sink(fig, "scene")
    return sink.take("scene")


# ---------------------------------------------------------------- tables
STEP = {"adaptive": lambda g: f"rtol {attr(g, 'rtol'):g}",
        "substepped": lambda g: f"{attr(g, 'h'):g}/{attr(g, 'substeps')}",
        "iterated": lambda g: f"{attr(g, 'h'):g} x{attr(g, 'iterations')}"}


def step_of(g):
    return STEP.get(attr(g, "step_kind"), lambda g: f"{attr(g, 'h'):g}")(g)


def opt(g, key, spec="{:.3e}"):
    return spec.format(attr(g, key)) if key in g.attrs else "-"


def main_table(f):
    key, _ = P.error_key(f)
    rows = []
    for rid, g in f["runs"].items():
        rows.append([attr(g, "label"), step_of(g), attr(g, "steps"), attr(g, "fixed_point_updates"),
                     attr(g, "cg_iterations"), opt(g, "solver_time_s", "{:.3f}"), opt(g, "setup_time_s", "{:.3f}"),
                     attr(g, "repeats", 1), opt(g, key), opt(g, "observed_order", "{:.2f}"),
                     opt(g, "energy_rate_W"), attr(g, "status"), rid])
    return table(["method", "h [s] | rtol", "steps", "updates", "CG iterations", "solver [s]", "setup [s]", "timings",
                  {"error_final_m": "e_rms(t_end) [m]", "error_rms_m": "e_rms(t_end) [m]", "error_l2_m": "e_l2 [m]",
                   "error_max_m": "e_max [m]"}.get(key, key), "order", "dE/dt [W]", "status", "run"],
                 rows, "main")


def equal_accuracy(f):
    """The equal-accuracy table of /work_precision, as bench_integrators prints it."""
    w = f["work_precision"]
    labels = attr(w, "labels").split(",")
    targets = w["targets"][()]
    cost, ratio, bound = w["solver_time"][()], w["ratio"][()], w["upper_bound"][()]
    min_error, unresolved = w["min_error"][()], w["unresolved"][()].ravel()
    fastest, tied = w["fastest"][()].ravel(), w["tied"][()]
    baseline = attr(w, "baseline")
    rows = []
    for m, label in enumerate(labels):
        cells = [label]
        for j in range(len(targets)):
            if unresolved[j]:
                cells.append("unresolved")
            elif cost[m, j] > 0:
                cells.append(f"{'≤ ' if bound[m, j] else ''}{cost[m, j]:.3g} s ({ratio[m, j]:.2f}x)"
                             if ratio[m, j] > 0 else f"{'≤ ' if bound[m, j] else ''}{cost[m, j]:.3g} s")
            else:
                cells.append("- (failed)" if min_error[m] < 0 else f"- (min {min_error[m]:.1e} m)")
        rows.append(cells)
    best = ["fastest"] + [labels[i] if i >= 0 else "-" for i in fastest]
    ties = []
    for j in range(len(targets)):
        t = [labels[m] for m in range(len(labels)) if tied[j, m] and m != fastest[j]]
        ties.append(", ".join(t) if t else "")
    header = ["method"] + [f"{g:g} m" for g in targets]
    body = table(header, rows + [best] + ([["tied with the fastest"] + ties] if any(ties) else []), "equal-accuracy",
                 f"solver time at the target, ratio to {baseline}")
    return body, [labels[i] if i >= 0 else "" for i in fastest]


def settings_table(f):
    """Every scalar attribute of every run, one row per run (a <details> each)."""
    out = []
    for rid, g in f["runs"].items():
        items = [(k, fmt(g.attrs[k])) for k in sorted(g.attrs)]
        out.append(f"<details><summary>{esc(rid)}: {esc(attr(g, 'label'))}, {esc(step_of(g))}, "
                   f"{esc(attr(g, 'status'))}</summary>" + table(["setting", "value"], items, "settings") +
                   "</details>")
    return "\n".join(out)


def contact_table(f):
    rows = []
    for rid, g in f["runs"].items():
        s = g["step_stats"][()] if "step_stats" in g else None
        colliding = int(s["colliding"].max()) if s is not None and len(s) else 0
        crossing = int(g["crossing_pairs"][()].max()) if "crossing_pairs" in g and g["crossing_pairs"].size else None
        depth = float(g["penetration/max_depth"][()].max()) if "penetration/max_depth" in g and \
            g["penetration/max_depth"].size else None
        sc = g.get("self_contact")
        if colliding <= 0 and crossing is None and depth is None and sc is None:
            continue  # no contact (-1: a SUNDIALS row, which does not count them per step)
        rows.append([rid, attr(g, "status"), colliding if colliding >= 0 else "-", "-" if depth is None else f"{depth:.3e}",
                     opt(g, "contact_power_W"), "-" if crossing is None else crossing,
                     attr(g, "collision_self", "-")] +
                    ([attr(sc, k, "-") for k in ("candidates", "repulsions", "collisions", "zone_passes",
                                                 "projections", "pair_impulses")] +
                     [opt(sc, "detection_s", "{:.3f}"), opt(sc, "response_s", "{:.3f}")]
                     if sc is not None else ["-"] * 8))
    if not rows:
        return ""
    return table(["run", "status", "colliding (max)", "depth in an obstacle (max) [m]", "contact power [W]",
                  "crossing pairs (max)", "self-contact", "candidates", "repulsions", "collisions", "zone passes",
                  "projections", "pair impulses", "detection [s]", "response [s]"], rows, "contact")


def cg_per_step(f, sink):
    """CG iterations per accepted step: each label's first fixed-step run that uses the PCG."""
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    lines = 0
    for k, (label, runs) in enumerate(P.runs_by_label(f).items()):
        for g in runs:
            if "step_stats" not in g or attr(g, "step_kind") == "adaptive":
                continue
            s = g["step_stats"][()]
            s = s[s["status"] == 0]
            s = s[:: thin(len(s))]
            if len(s) and s["cg_iterations"].max() > 0:
                st = P.style(label, k)
                st.pop("marker")
                ax.plot(s["t"], s["cg_iterations"], linewidth=0.9, label=f"{label}, {step_of(g)}", **st)
                lines += 1
                break
    if not lines:
        plt.close(fig)
        return ""
    ax.set_xlabel("t [s]")
    ax.set_ylabel("CG iterations per step")
    ax.grid(True, alpha=0.3)
    ax.set_title(P.title(f, "CG iterations per accepted step (each method's first run)"), fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    sink(fig, "cg_per_step")
    return sink.take("cg_per_step")


def reference_section(f):
    if "reference" not in f:
        return "<p>No reference (<code>--reference none</code>): no errors, orders or equal-accuracy table.</p>"
    r = f["reference"]
    keys = ["integrator", "label", "step_kind", "rtol", "atol", "h", "status", "steps", "solver_time_s",
            "error_estimate_m", "cross_check", "cross_check_error_estimate_m", "cross_check_difference_m",
            "sundials_settings", "message"]
    return table(["", "value"], [(k, fmt(r.attrs[k])) for k in keys if k in r.attrs], "reference")


def machine_rows(f, path):
    keys = ["created", "git_commit", "host", "compiler", "build_type", "hardware_threads", "mpi_ranks", "schema",
            "error_metric"]
    return [("file", os.path.abspath(path))] + [(k, fmt(f.attrs[k])) for k in keys if k in f.attrs]


def bench_page(f, path, spec, toml_text, sink):
    sections = []
    s = f["scene"]
    n_fixed = num(s, "n_fixed", int) if "n_fixed" in s.attrs else 0
    stiffness = f"{num(s, 'numerical_stiffness'):.4g}" if "numerical_stiffness" in s.attrs else "-"
    sections.append(("scene", f"Scene: {attr(s, 'name')}",
                     f"<p>N = {num(s, 'n_particles', int)} particles ({n_fixed} fixed), t_end = "
                     f"{num(s, 't_end'):g} s, h = {num(s, 'h'):g} s, numerical stiffness h²k/(ρl²) = "
                     f"{stiffness}, explicit terms: {esc(attr(s, 'explicit_terms'))}.</p>" +
                     scene_figure(f, spec, sink) +
                     f"<details><summary>scene file ({esc(attr(s, 'source'))})</summary><pre>{esc(toml_text)}</pre>"
                     "</details>"))
    sections.append(("reference", "Reference", reference_section(f)))
    sections.append(("main-table", "Main table", main_table(f)))
    fastest = []
    if "work_precision" in f:
        body, fastest = equal_accuracy(f)
        P.plot_work_precision(f, sink, "", [])
        reasons = str(attr(f["work_precision"], "stop_reasons", "")).splitlines()[:MAX_LINES]
        if reasons:  # --sweep-to-targets
            body += f"<p>Why each method's sweep stopped:</p><ul>{''.join(f'<li>{esc(r)}</li>' for r in reasons)}</ul>"
        sections.append(("equal-accuracy", "Equal accuracy and work-precision",
                         body + sink.take("work_precision")))
    P.plot_observed_order(f, sink, "", [])
    if "observed_order" in sink.svg:
        sections.append(("convergence", "Convergence (observed order)", sink.take("observed_order")))
    P.plot_energy(f, sink, "", [])
    sections.append(("energy", "Energy over time", sink.take("energy")))
    cg = cg_per_step(f, sink)
    if cg:
        sections.append(("cg", "CG iterations per step", cg))
    contacts = contact_table(f)
    P.plot_fig_4_3(f, sink, "", [])
    P.plot_virtual(f, sink, "", [])
    if contacts or "fig_4_3" in sink.svg or "virtual" in sink.svg:
        sections.append(("contact", "Contact", contacts + sink.take("fig_4_3") + sink.take("virtual")))
    sections.append(("settings", "Every row's settings", settings_table(f)))
    inspect = "build/bench/clothbench_inspect"
    rows = [(rid, f"{inspect} {shell_quote(os.path.abspath(path))} rerun {shell_quote(rid)}")
            for rid in f["runs"]]
    sections.append(("rerun", "Recompute a run",
                     "<p>Each command recomputes the run in-process from the scene and settings stored with it "
                     "and compares its end state bit for bit (the same build and thread count); "
                     "<code>command RUN</code> in place of <code>rerun RUN</code> prints a shell script that "
                     "does the same with bench_integrators.</p>" + table(["run", "command"], rows, "commands")))
    return sections, fastest


def shell_quote(s):
    return "'" + s.replace("'", "'\\''") + "'"


def sizes_page(f, path, sink):
    v = f["scale_verdict"]
    labels = attr(v, "labels").split(",")
    sizes = v["sizes"][()].ravel()
    targets = v["targets"][()]
    cost, bound = v["cost_s"][()], v["upper_bound"][()]
    fastest = [[x.decode() for x in row] for row in v["fastest"][()]]
    files = [x.decode() for x in v["result_files"][()].ravel()]
    sizes = sizes[:MAX_SIZES]
    rows = []
    for s, n in enumerate(sizes):
        for j, t in enumerate(targets):
            cells = [n, f"{t:g}", fastest[s][j] or "-"]
            for m in range(len(labels)):
                c = cost[s, j, m]
                cells.append(f"{'≤ ' if bound[s, j, m] else ''}{c:.3g}" if c > 0 else "-")
            rows.append(cells)
    P.plot_scale(f, sink, "", [])
    sections = [("verdict", "Scale verdict", table(["N", "target [m]", "fastest"] + labels, rows, "verdict",
                                                   "solver time [s] at the target") + sink.take("scale"))]
    for s, n in enumerate(sizes):
        g = f["sizes"][f"n{n}"]
        wp = g["work_precision"]
        reasons = str(attr(wp, "stop_reasons", "")).splitlines()[:MAX_LINES]
        link = size_page_link(path, files[s], int(n))
        sections.append((f"n{n}", f"N = {n} ({attr(g, 'nu')}×{attr(g, 'nv')}): {files[s]}", link +
                         (f"<p>Why each method's sweep stopped:</p><ul>{''.join(f'<li>{esc(r)}</li>' for r in reasons)}"
                          "</ul>" if reasons else "") + equal_accuracy({"work_precision": wp})[0]))
    return sections, fastest


def size_page_link(path, stored, n):
    """A link to the size's own page where scripts/report wrote one beside
    it: only for the file the sweep itself names for size n (the verdict's
    stem + ".n<N>.h5", bench_integrators --sizes), by its plain relative
    name, whatever the stored entry says; "" otherwise."""
    own = os.path.splitext(os.path.basename(path))[0] + f".n{n}.h5"
    if stored != own:
        return ""
    page = os.path.splitext(own)[0] + ".html"
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isfile(os.path.join(folder, page)):
        return ""
    return f'<p>The size\'s own page: <a href="./{urllib.parse.quote(page)}">{esc(page)}</a></p>'


def stress_page(f, sink):
    P.plot_stability(f, sink, "", [])
    return [(f"stability-{k}", f"Stability map: {k[len('stability_'):]}", svg) for k, svg in sink.svg.items()
            if k.startswith("stability_")], []


CSS = """body{font:14px/1.4 sans-serif;margin:1.5em auto;max-width:1200px;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.6em 0;font-size:12px}td,th{border:1px solid #ccc;padding:2px 6px;
text-align:left}th{background:#f0f0f0}caption{text-align:left;font-style:italic}figure{margin:.6em 0}
figure svg{max-width:100%;height:auto}pre{background:#f7f7f7;padding:.5em;overflow:auto;font-size:12px}
nav a{margin-right:1em}code{background:#f3f3f3}"""
