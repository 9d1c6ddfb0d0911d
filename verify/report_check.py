#!/usr/bin/python3
"""ctest: scripts/report's page of a result file, opened in a real browser.

    verify/report_check.py REPORT FILE.h5 WORKDIR [--page PAGE] [--screenshot PNG]

Writes the page of FILE.h5 into WORKDIR with scripts/report (or takes
PAGE, the one bench_integrators --report wrote beside the file), opens it from
its file:// address in headless Chromium (Debian's chromium and
chromium-driver, driven by python3-selenium) and checks
  - the browser fetched nothing but the page itself and the data: URIs
    inside it (Chrome's performance log: every Network.requestWillBeSent)
    and logged no error (a blocked
    request or a broken inline figure shows there);
  - the page's verdict names the same fastest methods as the file: the
    'fastest' row of the equal-accuracy table against /work_precision's
    fastest (bench_integrators files), or the verdict table's fastest column
    against /scale_verdict's (--sizes files);
  - every section the file calls for is there, each plot is an inline SVG
    with a drawing in it;
  - the checker itself sees a request: a copy of the page with one external
    image must be flagged (so a pass is not a checker that sees nothing).
Exit 0 when all hold, 1 with what failed.
"""
import argparse
import json
import os
import re
import subprocess
import sys

import h5py
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By


def browser():
    o = webdriver.ChromeOptions()
    o.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,2400"):
        o.add_argument(a)
    o.set_capability("goog:loggingPrefs", {"performance": "ALL", "browser": "ALL"})
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=o)


def open_page(d, page):
    """Loads the page; returns (requested URLs, browser errors)."""
    d.get("file://" + os.path.abspath(page))
    urls = []
    for e in d.get_log("performance"):
        m = json.loads(e["message"])["message"]
        if m["method"] == "Network.requestWillBeSent":
            urls.append(m["params"]["request"]["url"])
    errors = [e["message"] for e in d.get_log("browser") if e["level"] == "SEVERE"]
    return urls, errors


def text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("report")
    p.add_argument("file")
    p.add_argument("workdir")
    p.add_argument("--screenshot")
    p.add_argument("--page", help="check this page (written by bench_integrators --report) instead of writing one")
    a = p.parse_args()
    os.makedirs(a.workdir, exist_ok=True)
    page = os.path.join(a.workdir, os.path.splitext(os.path.basename(a.file))[0] + ".html")
    if a.page:  # the page bench_integrators --report wrote beside the file
        page = a.page
        with open(page, "rb") as f:
            if not f.read(27) == b"<!-- clothbench report -->\n":
                print(f"{page}: not a page of scripts/report")
                return 1
    else:
        r = subprocess.run([a.report, a.file, "--out", page], capture_output=True, text=True)
        if r.returncode != 0:
            print(f"report failed ({r.returncode}): {r.stderr.strip()}")
            return 1
    failures = []
    with h5py.File(a.file, "r") as f:
        bench = "runs" in f
        if bench:
            want_sections = ["scene", "reference", "main-table", "energy", "settings", "rerun"]
            if "work_precision" in f:
                want_sections.append("equal-accuracy")
                w = f["work_precision"]
                labels = text(w.attrs["labels"]).split(",")
                want = [labels[i] if i >= 0 else "-" for i in w["fastest"][()].ravel()]
            else:
                want = None
            n_runs = len(f["runs"])
        else:
            v = f["scale_verdict"]
            want_sections = ["verdict"]
            want = [[x.decode() or "-" for x in row] for row in v["fastest"][()]]
            n_runs = None
    d = browser()
    try:
        urls, errors = open_page(d, page)
        own = "file://" + os.path.abspath(page)
        # data: URIs (a rasterised figure inside its SVG) are the page's own bytes, not requests.
        other = [u for u in urls if u != own and not u.startswith("data:")]
        if other:
            failures.append(f"the page requested {other}")
        if errors:
            failures.append(f"browser errors: {errors}")
        for s in want_sections:
            if not d.find_elements(By.ID, s):
                failures.append(f"section #{s} missing")
        for fig in d.find_elements(By.CSS_SELECTOR, "figure.plot"):
            if not fig.find_elements(By.CSS_SELECTOR, "svg path"):
                failures.append(f"figure {fig.get_attribute('id')} has no drawing")
        if want is not None and bench:
            row = [r for r in d.find_elements(By.CSS_SELECTOR, "table.equal-accuracy tr")
                   if r.find_elements(By.TAG_NAME, "td") and r.find_elements(By.TAG_NAME, "td")[0].text == "fastest"]
            got = [c.text for c in row[0].find_elements(By.TAG_NAME, "td")[1:]] if row else None
            if got != want:
                failures.append(f"equal-accuracy fastest {got}, the file's {want}")
        elif want is not None:
            got = [c.text for c in d.find_elements(By.CSS_SELECTOR, "table.verdict tbody tr td:nth-child(3)")]
            flat = [x for row in want for x in row]
            if got != flat:
                failures.append(f"verdict fastest {got}, the file's {flat}")
        if n_runs is not None:
            cmds = d.find_elements(By.CSS_SELECTOR, "table.commands tbody tr")
            if len(cmds) != n_runs:
                failures.append(f"{len(cmds)} rerun commands for {n_runs} runs")
        if a.screenshot:
            d.set_window_size(1280, 1800)
            d.save_screenshot(a.screenshot)
        # The checker must see a request when there is one.
        planted = os.path.join(a.workdir, "planted.html")
        with open(page, encoding="utf-8") as src, open(planted, "w", encoding="utf-8") as dst:
            # Without the page's Content-Security-Policy, which would block
            # the request (a blocked one shows as a browser error instead).
            body = re.sub(r'<meta http-equiv="Content-Security-Policy"[^>]*>', "", src.read())
            dst.write(body.replace("<body>", '<body><img src="http://127.0.0.1:9/x.png" alt="">', 1))
        urls, _ = open_page(d, planted)
        if not any(u.startswith("http://127.0.0.1:9/") for u in urls):
            failures.append(f"the checker missed the planted request (saw {urls})")
        os.unlink(planted)
    finally:
        d.quit()
    for msg in failures:
        print(msg)
    if not failures:
        print(f"{page}: loads offline ({len(urls)} requests in the planted copy, 1 in the page), the verdict matches")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
