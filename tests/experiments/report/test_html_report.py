"""The HTML report users open: `snakemake --report` on the smoke grid, loaded in a real browser.

Checks that every figure (PNG) and table (HTML) of the grid is embedded in the self-contained file, with its
category and caption, that headless Chromium renders Snakemake's report app, and that a screenshot of the
app showing a figure is not blank. Chromium comes from Debian's package; the test installs it when it runs
as root with apt-get (as on CI), and skips, saying why, where it cannot.
"""

import base64
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from _apt import apt_lock

from experiments.report import catalog

pytestmark = pytest.mark.slow

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--window-size=1600,900", "--virtual-time-budget=30000"]
# Snakemake's report is a JavaScript app with no URL routing: this clicks through it the way a user would,
# after the app has rendered: every (sub)category's list, every result in it opened from the list (its eye
# button calls App.setView), and last the figure given, shown from its category's list. Any uncaught error
# lands in the console log that the test reads.
CLICK_THROUGH = """<script>
window.addEventListener("load", function () {
  var steps = [];
  function open(c, sc, p) {
    steps.push(function () { app.setView({navbarMode: "menu"}); });    // back to the menu, as a user goes
    steps.push(function () {
      if (Object.keys(categories[c]).length > 1) {
        app.setView({navbarMode: "subcategory", category: c, subcategory: sc});
      } else {
        app.showCategory(c);
      }
    });
    steps.push(function () {
      var kind = results[p].mime_type === "text/html" ? "html" : "img";
      app.setView({content: kind, contentPath: results[p].data_uri, resultPath: p});
    });
  }
  var last;
  Object.keys(categories).forEach(function (c) {
    Object.keys(categories[c]).forEach(function (sc) {
      categories[c][sc].forEach(function (p) {
        open(c, sc, p);
        if (p.endsWith("/%s.png")) { last = [c, sc, p]; }
      });
    });
  });
  open(last[0], last[1], last[2]);
  steps.forEach(function (step, i) { setTimeout(step, 200 * (i + 1)); });
});
</script>"""


def _chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found:
        return found
    if not shutil.which("apt-get"):
        pytest.skip("chromium is not installed and there is no apt-get to install Debian's package")
    if os.geteuid() != 0:
        pytest.skip("chromium is not installed and installing Debian's package needs root (apt-get install -y "
                    "chromium)")
    env = os.environ | {"DEBIAN_FRONTEND": "noninteractive"}
    install = ["apt-get", "install", "-y", "chromium"]
    with apt_lock():
        if subprocess.run(install, capture_output=True, env=env, timeout=900).returncode != 0:
            subprocess.run(["apt-get", "update"], capture_output=True, env=env, timeout=600)   # stale lists
            proc = subprocess.run(install, capture_output=True, text=True, env=env, timeout=900)
            assert proc.returncode == 0, f"apt-get install chromium failed: {proc.stderr[-2000:]}"
    return shutil.which("chromium")


@pytest.fixture(scope="module")
def report(smoke_workdir, snakemake):
    out = smoke_workdir / "report.html"
    proc = snakemake(smoke_workdir, "--report", str(out), "smoke")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "(ERROR/" not in proc.stderr and "(WARNING/" not in proc.stderr, proc.stderr[-3000:]  # captions
    return smoke_workdir, out.read_text(encoding="utf-8")


def browse(html_file: Path, tmp_path: Path, *what: str) -> subprocess.CompletedProcess:
    chromium = _chromium()
    profile = tmp_path / f"profile-{len(list(tmp_path.glob('profile-*')))}"     # a fresh one per run
    return subprocess.run([chromium, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *what,
                           html_file.as_uri()], capture_output=True, text=True, timeout=180, cwd=tmp_path)


def test_report_embeds_every_figure_and_table_with_category_and_caption(report):
    workdir, html = report
    figures = sorted((workdir / "results" / "smoke" / "figures").glob("*.png"))
    tables = sorted((workdir / "results" / "smoke" / "tables").glob("*.html"))
    assert {"rmse_vs_noise", "failure_map", "coverage"} <= {f.stem for f in figures}
    assert {"comparison", "coverage_by_method"} <= {f.stem for f in tables}
    for f in figures + tables:
        data = base64.b64encode(f.read_bytes()).decode()
        assert f"filename={f.name};base64,{data}" in html, f"{f.name} is not embedded in the report"
    for name in ("failure_map", "coverage"):
        first_words = " ".join(catalog.caption_of(name).split()[:6])
        assert first_words in " ".join(html.replace("\\n", " ").split()), f"caption of {name} missing"
    for category in ("accuracy", "failures", "uncertainty"):
        assert f'"{category}": {{' in html
    # One label per result: with two, the report app takes a two-valued label for a toggle and a category
    # of two results crashes when a result is opened from its list (seen with name + title labels).
    labels = re.findall(r'"labels": (\{[^}]*\}|null)', html)
    assert len(labels) >= len(figures) + len(tables)
    assert all(len(json.loads(lab)) == 1 for lab in labels if lab != "null"), labels[:3]


def test_chromium_renders_the_report_and_shows_a_figure(report, tmp_path):
    workdir, html = report
    page = tmp_path / "report.html"
    page.write_text(html, encoding="utf-8")
    dom = browse(page, tmp_path, "--dump-dom")
    assert dom.returncode == 0, dom.stderr[-2000:]
    # The workflow description is a JavaScript string in the file; only the running app makes it an element.
    assert '<h1 class="title">Identifying the vibration' in dom.stdout
    assert '<h1 class="title">Identifying the vibration' not in html

    driven = tmp_path / "failure_map.html"
    end = html.rindex("</body>")
    driven.write_text(html[:end] + CLICK_THROUGH % "failure_map" + html[end:], encoding="utf-8")
    dom = browse(driven, tmp_path, "--dump-dom", "--enable-logging=stderr", "--v=0")
    assert "Uncaught" not in dom.stderr, [line for line in dom.stderr.splitlines() if "CONSOLE" in line]
    assert 'src="data:image/png;charset=utf8;filename=failure_map.png;base64,' in dom.stdout
    shot = workdir / "report_failure_map.png"
    proc = browse(driven, tmp_path, f"--screenshot={shot}")
    assert proc.returncode == 0 and shot.exists(), proc.stderr[-2000:]
    rgb = matplotlib.image.imread(shot)[..., :3]
    assert (rgb.std(axis=(0, 1)) > 0.1).all()                      # not a blank page
    assert np.mean(rgb.min(axis=2) < 0.9) > 0.1                     # ink on more than 10 % of it
    # The failure map's colour bar always spans the darkest red of "Reds" (103, 0, 13): the figure is drawn.
    dark_red = np.abs(rgb * 255 - np.array([103, 0, 13])).max(axis=2) < 30
    assert dark_red.sum() > 50
