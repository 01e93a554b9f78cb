"""Regenerate the report pictures in docs/ from real runs: report.png as written, report.html as headless
Chromium shows it.

    .venv/bin/python docs/make_reports.py [--work DIR]

1. ``gsr curve samples/curves/bspline_07_noisy.csv --truth ... --units mm --max-distance 0.3 --seed 1``;
2. ``gsr surface samples/surfaces/inset_extrude.obj --units mm --seed 1``;
3. ``gsr curve helix.csv --units mm --max-distance 0.05 --seed 1`` on a helix made here (a space curve);
4. each report.html screenshotted by Debian's ``chromium`` (``--headless --screenshot``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from gsr_cad.cli import main as gsr

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent
CHROMIUM = ["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
            "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
            "--hide-scrollbars", "--virtual-time-budget=15000"]


def screenshot(page: Path, png: Path, height: int) -> None:
    """``page`` as Chromium draws it, 1300 pixels wide, into ``png``."""
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run([*CHROMIUM, f"--user-data-dir={profile}", f"--window-size=1300,{height}",
                        f"--screenshot={png}", page.resolve().as_uri()], check=True, capture_output=True,
                       timeout=300)


def helix(path: Path) -> Path:
    """Two turns of a helix of radius 20 mm rising 25 mm, 400 points, as x, y, z rows in ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    t = np.linspace(0.0, 4.0 * np.pi, 400)
    np.savetxt(path, np.c_[20.0 * np.cos(t), 20.0 * np.sin(t), 25.0 * t / (4.0 * np.pi)], delimiter=",")
    return path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, help="where the runs go (default: a temporary directory)")
    args = parser.parse_args()
    if shutil.which("chromium") is None:
        sys.exit("chromium is not installed (apt-get install chromium)")
    work = args.work or Path(tempfile.mkdtemp(prefix="gsr-reports-"))
    curves, surfaces = REPO / "samples" / "curves", REPO / "samples" / "surfaces"
    runs = {
        "curve": ["curve", curves / "bspline_07_noisy.csv", "--truth", curves / "bspline_07_noisy.truth.csv",
                  "--units", "mm", "--max-distance", "0.3", "--seed", "1"],
        "surface": ["surface", surfaces / "inset_extrude.obj", "--units", "mm", "--seed", "1"],
        "curve_3d": ["curve", helix(work / "helix.csv"), "--units", "mm", "--max-distance", "0.05", "--seed", "1"],
    }
    pictures = {"curve": "curve_report_noisy.png", "surface": "surface_report.png", "curve_3d": "curve_report_3d.png"}
    heights = {"curve": 2500, "surface": 1900, "curve_3d": 2700}
    for name, argv in runs.items():
        out = work / name
        code = gsr([str(a) for a in [*argv, "-o", out, "--formats", "none", "--quiet"]])
        if code != 0:
            sys.exit(f"gsr {name} failed with exit code {code}")
        shutil.copyfile(out / "report.png", DOCS / pictures[name])
        screenshot(out / "report.html", DOCS / f"{name}_report_html.png", heights[name])
    print(f"runs in {work}; pictures in {DOCS}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
