"""The reports as a user opens them: check's ``index.html`` and refine's summary page in
headless Chromium (Debian's ``chromium``, driven by playwright), images loaded, tables holding
the figures of report.json / refine.json, and a screenshot of each kept as an artifact
(``PHYSDSL_TEST_ARTIFACTS`` or the test's tmp folder).

Skipped, with the reason, where playwright or a Chromium binary is missing
(``pip install physdsl[browser]``; ``apt-get install chromium``; or ``PHYSDSL_CHROMIUM=PATH``).
"""
from __future__ import annotations

import importlib.util
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = os.environ.get("PHYSDSL_CHROMIUM") or shutil.which("chromium") \
    or shutil.which("chromium-browser")

pytestmark = [
    pytest.mark.skipif(importlib.util.find_spec("playwright") is None,
                       reason="no browser test: playwright is not installed "
                              "(pip install 'physdsl[browser]')"),
    pytest.mark.skipif(CHROMIUM is None,
                       reason="no browser test: no Chromium binary (apt-get install chromium, "
                              "or PHYSDSL_CHROMIUM=/path/to/chromium)"),
]

# a ball thrown in vacuum, measured every 20 ms with 1 cm noise; its start position unknown
SCENE = """\
scene throw {
  world { timestep: 10 ms  integrator: rk4 }
  body ball {
    shape: sphere(radius: 5 cm)
    mass: 200 g
    position ~ normal((0, 0, 1) m, 5 cm)
    velocity: (2, 0, 3) m/s
  }
  observe ball.position from "track.csv" { noise: 1 cm }
}
"""


def _write_case(folder: Path) -> Path:
    t = np.arange(0, 0.5 + 1e-9, 0.02)
    x = np.stack([0.02 + 2 * t, 0 * t, 0.97 + 3 * t - 0.5 * 9.81 * t ** 2], 1)
    x += np.random.default_rng(3).normal(0, 0.01, x.shape)
    rows = ["t,x,y,z"] + [f"{ti:.3f},{a:.6f},{b:.6f},{c:.6f}" for ti, (a, b, c) in zip(t, x)]
    folder.mkdir(parents=True)
    (folder / "track.csv").write_text("\n".join(rows) + "\n")
    (folder / "throw.phys").write_text(SCENE)
    return folder / "throw.phys"


@pytest.fixture(scope="module")
def refined(tmp_path_factory) -> Path:
    """One round of refine (a MAP fit and its check): refine's page and round 0's report."""
    from physdsl.diagnose.refine import refine

    root = tmp_path_factory.mktemp("browser")
    scene = _write_case(root / "case")
    refine(scene, root / "out", max_rounds=0, backend="map", chains=1, warmup=50, samples=50,
           echo=lambda *_: None)
    return root / "out"


@pytest.fixture(scope="module")
def page():
    from playwright.sync_api import sync_playwright

    args = ["--no-sandbox"] if os.geteuid() == 0 else []  # Chromium refuses root otherwise
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=args)
        pg = browser.new_page(viewport={"width": 1100, "height": 900})
        yield pg
        browser.close()


@pytest.fixture
def artifacts(tmp_path) -> Path:
    folder = Path(os.environ.get("PHYSDSL_TEST_ARTIFACTS", tmp_path))
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _open(page, path: Path) -> None:
    page.goto(path.resolve().as_uri())
    page.wait_for_load_state("load")


def _images(page) -> list[tuple[str, int]]:
    return page.eval_on_selector_all("img", "els => els.map(e => [e.getAttribute('src'), "
                                            "e.complete ? e.naturalWidth : 0])")


def _tables(page) -> list[list[list[str]]]:
    return page.eval_on_selector_all(
        "table", "ts => ts.map(t => Array.from(t.rows).map(r => "
                 "Array.from(r.cells).map(c => c.innerText.trim())))")


def test_check_report_in_a_browser(refined, page, artifacts):
    from physdsl.diagnose.report import _num

    report_dir = refined / "round-0" / "check"
    _open(page, report_dir / "index.html")
    images = _images(page)
    assert len(images) >= 2 and all(w > 0 for _, w in images), images
    report = json.loads((report_dir / "report.json").read_text())
    tables = _tables(page)
    axes = [row for t in tables if t[0][:3] == ["axis", "n", "RMS σ"] for row in t[1:]]
    want = [[a["axis"], str(a["n"]), _num(a["rms_sigma"])]
            for o in report["observables"] for a in o["axes"]]
    assert [row[:3] for row in axes] == want and len(want) == 3
    windows = [row for t in tables if t[0][:2] == ["window", "kind"] for row in t[1:]]
    assert [row[3] for row in windows] == [_num(w["rms_sigma"]) for o in report["observables"]
                                           for w in o["windows"]]
    page.screenshot(path=str(artifacts / "check.png"), full_page=True)
    assert (artifacts / "check.png").stat().st_size > 10_000


def test_refine_summary_in_a_browser(refined, page, artifacts):
    _open(page, refined / "index.html")
    images = _images(page)
    assert [src for src, _ in images] == ["refine.png"] and images[0][1] > 0
    data = json.loads((refined / "refine.json").read_text())
    (table,) = [t for t in _tables(page) if t[0][0] == "round"]
    assert [row[0] for row in table[1:]] == [str(i) for i in range(len(data["rounds"]))]
    assert [row[5] for row in table[1:]] == [f"{r['rms_sigma']:.2f}" for r in data["rounds"]]
    assert [row[6] for row in table[1:]] == [f"{r['elpd']:.1f}" for r in data["rounds"]]
    # the round's report link leads to a page that loads
    page.click("text=check")
    page.wait_for_load_state("load")
    assert page.url.endswith("round-0/check/index.html") and page.title() == "physdsl check"
    _open(page, refined / "index.html")
    page.screenshot(path=str(artifacts / "refine.png"), full_page=True)
    assert (artifacts / "refine.png").stat().st_size > 5_000
