"""report.html: opens offline in headless Chromium with no console error and shows the target and the result.

Chromium is driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``): console errors,
uncaught exceptions and every network request are recorded, and the plotly figures are read back from
the page. Needs Debian's ``chromium`` (scripts/test.sh installs it when run as root); skips without it.
"""

from __future__ import annotations

import base64
import html
import json
import os
import re
import select
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from gsr_cad import html_report
from gsr_cad.errors import InputError
from gsr_cad.reconstruct.curve import reconstruct_curve
from gsr_cad.reconstruct.samples import get_sample
from gsr_cad.reconstruct.summary import add_model_units
from gsr_cad.reconstruct.surface import reconstruct_surface

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
         "--remote-debugging-pipe"]
FIGURES = """JSON.stringify(Array.from(document.querySelectorAll('.js-plotly-plot')).map(d => ({
  id: d.id, names: (d.data || []).map(t => t.name), types: (d.data || []).map(t => t.type),
  points: (d._fullData || []).map(t => (t.x || []).length), scenes: Object.keys(d._fullLayout || {})
    .filter(k => /^scene[0-9]*$/.test(k)).map(k => d._fullLayout[k].aspectmode),
  canvases: d.querySelectorAll('canvas').length, drawn: d.querySelectorAll('.main-svg').length > 0})))"""


class DevTools:
    """A Chromium process and its DevTools pipe (fd 3: commands in, fd 4: replies and events out)."""

    def __init__(self, profile: Path):
        to_chrome, self._write = os.pipe()
        self._read, from_chrome = os.pipe()

        def wire() -> None:  # via fresh copies: a pipe end may already sit on fd 3 or 4
            inbound, outbound = os.dup(to_chrome), os.dup(from_chrome)
            os.dup2(inbound, 3)
            os.dup2(outbound, 4)

        self.proc = subprocess.Popen([str(CHROMIUM), *FLAGS, f"--user-data-dir={profile}", "about:blank"],
                                     preexec_fn=wire, close_fds=False, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        os.close(to_chrome)
        os.close(from_chrome)
        self._buffer, self._next, self.events = b"", 0, []

    def _message(self, deadline: float) -> dict:
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._read], [], [], left)[0]:
                raise TimeoutError("no answer from Chromium")
            chunk = os.read(self._read, 1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed its DevTools pipe")
            self._buffer += chunk
        raw, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(raw)

    def call(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 60) -> dict:
        self._next += 1
        message = {"id": self._next, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._write, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            reply = self._message(deadline)
            if reply.get("id") == self._next:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_for(self, method: str, timeout: float = 60) -> dict:
        deadline = time.monotonic() + timeout
        for event in self.events:
            if event.get("method") == method:
                return event
        while True:
            event = self._message(deadline)
            self.events.append(event)
            if event.get("method") == method:
                return event

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=10)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._read)
        os.close(self._write)


def open_in_chromium(page: Path, profile: Path) -> tuple[list[dict], list[str], list[str]]:
    """Load ``page``; returns its plotly figures, its console errors and exceptions, and its non-file requests."""
    tools = DevTools(profile)
    try:
        target = tools.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = tools.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Page", "Network"):
            tools.call(f"{domain}.enable", session=session)
        tools.call("Page.navigate", {"url": page.resolve().as_uri()}, session=session)
        tools.wait_for("Page.loadEventFired", timeout=120)
        figures: list[dict] = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # plotly draws 3D scenes after the load event
            value = tools.call("Runtime.evaluate", {"expression": FIGURES, "returnByValue": True}, session=session)
            figures = json.loads(value["result"]["value"])
            if figures and all(f["drawn"] for f in figures):
                break
            time.sleep(0.5)
        time.sleep(1.0)
        tools.call("Runtime.evaluate", {"expression": "1"}, session=session)  # collect the events so far
    finally:
        tools.close()
    errors, requests = [], []
    for event in tools.events:
        method, params = event.get("method"), event.get("params", {})
        if method == "Runtime.exceptionThrown":
            errors.append(json.dumps(params.get("exceptionDetails", {}))[:500])
        elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            errors.append(json.dumps(params.get("args", []))[:500])
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            errors.append(params["entry"].get("text", "")[:500])
        elif method == "Network.requestWillBeSent":
            url = params.get("request", {}).get("url", "")
            if not url.startswith(("file:", "data:", "about:")):
                requests.append(url)
    return figures, errors, requests


pytestmark = pytest.mark.xdist_group("html_report")  # one worker builds the pages once


@pytest.fixture(scope="session")
def curve_page(tmp_path_factory):
    s = get_sample("bspline_07_noisy")
    result = reconstruct_curve(s.points, seed=1, units="mm", max_distance=0.03, initial_population=80,
                               population=20, generations=6)
    add_model_units(result)
    return html_report.curve_html(result, s.points, tmp_path_factory.mktemp("c") / "report.html", truth=s.truth_ctrl)


@pytest.fixture(scope="session")
def space_curve_page(tmp_path_factory):
    """The report of a real fit of a helix, with a ground truth (its control points lifted) to draw."""
    t = np.linspace(0, 4 * np.pi, 300)
    pts = np.column_stack([np.cos(t), np.sin(t), 0.2 * t])
    result = reconstruct_curve(pts, seed=0, units="mm", max_distance=1e-3, initial_population=60, population=16,
                               generations=6)
    add_model_units(result)
    truth = result.control_points + np.array([0.0, 0.0, 0.05])
    page = html_report.curve_html(result, pts, tmp_path_factory.mktemp("h") / "report.html", truth=truth,
                                  title="helix <b>&</b>")
    return page, result, pts


@pytest.fixture(scope="session")
def surface_page(tmp_path_factory):
    s = get_sample("inset_extrude")
    result = reconstruct_surface(s.target, seed=1, units="mm", population=10, initial_population=10, n_parents=4,
                                 n_perturb=2, n_newcomers=2, generations=2)
    add_model_units(result)
    return html_report.surface_html(result, tmp_path_factory.mktemp("s") / "report.html"), result


def test_the_page_is_self_contained(curve_page, surface_page):
    for page in (curve_page, surface_page[0]):
        text = page.read_text(encoding="utf-8")
        assert "<script src=" not in text and "<link" not in text  # nothing to fetch (Chromium checks requests)
        assert "Plotly.newPlot" in text and len(text) > 1_000_000  # plotly.js itself is inline
        assert [p.name for p in page.parent.iterdir()] == ["report.html"]  # written atomically, no temp left
    text = curve_page.read_text(encoding="utf-8")
    assert "lengths in mm" in text and "max-distance tolerance 0.03" not in text  # 0.03 is a fraction here
    assert "max-distance tolerance" in text and " mm (3 %)" in text


needs_chromium = pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed "
                                    "(/usr/bin/chromium; scripts/test.sh installs it when run as root)")


@needs_chromium
def test_curve_report_loads_in_chromium_with_target_and_result(curve_page, tmp_path):
    figures, errors, requests = open_in_chromium(curve_page, tmp_path / "profile")
    assert errors == [] and requests == []
    by_id = {f["id"]: f for f in figures}
    assert {"shape", "deviation", "history", "genome", "convergence"} <= set(by_id)
    assert all(f["drawn"] for f in figures)
    assert {"target", "result", "control polygon", "ground truth", "worst point"} <= set(by_id["shape"]["names"])
    assert {"deviation", "worst point", "tolerance"} <= set(by_id["deviation"]["names"])


def figure_data(page: Path, div_id: str) -> list[dict]:
    """The traces plotly is given for the figure ``div_id`` (the JSON of its ``Plotly.newPlot`` call)."""
    text = page.read_text(encoding="utf-8")
    call = re.search(r'Plotly\.newPlot\(\s*"' + div_id + r'",\s*', text)
    data, _ = json.JSONDecoder().raw_decode(text, call.end())
    return data


def xyz(trace: dict) -> np.ndarray:
    """A trace's points as rows, its typed arrays (``{"dtype", "bdata"}``, base64) decoded."""
    def column(value):
        if isinstance(value, dict):
            return np.frombuffer(base64.b64decode(value["bdata"]), dtype=value["dtype"])
        return np.asarray(value, dtype=float)

    return np.column_stack([column(trace[k]) for k in "xyz"])


def test_a_space_curve_page_has_3d_traces_with_every_point(space_curve_page):
    from gsr_cad.plots import CURVE_SAMPLES

    page, result, pts = space_curve_page
    traces = {t["name"]: t for t in figure_data(page, "shape")}
    assert {n: t["type"] for n, t in traces.items()} == {n: "scatter3d" for n in (
        "target", "result", "control polygon", "ground truth", "worst point")}
    np.testing.assert_allclose(xyz(traces["target"]), pts)
    np.testing.assert_allclose(xyz(traces["control polygon"]), result.control_points)
    assert len(xyz(traces["result"])) == CURVE_SAMPLES and len(xyz(traces["worst point"])) == 1
    diag = result.config["target"]["diagonal"]
    colour = xyz({k: traces["result"]["marker"]["color"] for k in "xyz"})[:, 0]
    assert colour.max() == pytest.approx(result.metrics["data_to_fit_max"] * diag, rel=0.05)  # in mm
    history = figure_data(page, "history")
    assert all(t["type"] == "scatter3d" for t in history)
    np.testing.assert_allclose(xyz(history[-1]), result.control_points)
    text = page.read_text(encoding="utf-8")
    assert "helix &lt;b&gt;&amp;&lt;/b&gt;: curve report" in text and "<b>&</b>" not in text


@needs_chromium
def test_space_curve_report_loads_in_chromium_as_3d_scenes(space_curve_page, tmp_path):
    page, result, pts = space_curve_page
    figures, errors, requests = open_in_chromium(page, tmp_path / "profile")
    assert errors == [] and requests == []
    by_id = {f["id"]: f for f in figures}
    assert {"shape", "deviation", "history", "genome", "convergence"} <= set(by_id)
    assert all(f["drawn"] for f in figures)
    shape = by_id["shape"]
    assert dict(zip(shape["names"], shape["types"])) == {n: "scatter3d" for n in (
        "target", "result", "control polygon", "ground truth", "worst point")}
    counts = dict(zip(shape["names"], shape["points"]))
    assert counts["target"] == len(pts) and counts["control polygon"] == len(result.control_points)
    assert shape["scenes"] == ["data"] and shape["canvases"] > 0  # a WebGL scene at equal scale
    assert by_id["history"]["scenes"] == ["data"] and by_id["deviation"]["scenes"] == []
    assert by_id["history"]["points"][-1] == len(result.control_points)


@needs_chromium
def test_surface_report_loads_in_chromium_with_target_and_result(surface_page, tmp_path):
    page, result = surface_page
    figures, errors, requests = open_in_chromium(page, tmp_path / "profile")
    assert errors == [] and requests == []
    by_id = {f["id"]: f for f in figures}
    assert {"surfaces", "history", "convergence", "front"} <= set(by_id) and all(f["drawn"] for f in figures)
    side = dict(zip(by_id["surfaces"]["names"], by_id["surfaces"]["types"]))
    assert side == {"target": "mesh3d", "result": "mesh3d", "control mesh": "scatter3d"}
    # the history slider holds the template and every step up to the result (two traces per step)
    assert len(by_id["history"]["names"]) == 2 * min(len(result.genome) + 1, html_report.HISTORY_STEPS)


def test_the_surface_figure_colours_the_result_by_its_distance_in_model_units(surface_page):
    page, result = surface_page
    text = html.unescape(page.read_text(encoding="utf-8"))
    assert "distance to target, mm" in text and "lengths in mm" in text
    assert "the paper's mixed mean distance" in text
    assert "accuracy/complexity front" in text and result.metrics["front"]


def test_bad_results_raise_typed_errors(tmp_path):
    from gsr_cad.reconstruct.result import Result

    surface = Result(kind="surface", config={}, seed=None, genome=(), metrics={}, history=[])
    with pytest.raises(InputError):
        html_report.curve_html(surface, np.zeros((5, 2)), tmp_path / "r.html")
    curve = Result(kind="curve", config={}, seed=None, genome=(), metrics={}, history=[],
                   control_points=np.zeros((4, 2)))
    with pytest.raises(InputError):
        html_report.surface_html(curve, tmp_path / "r.html")
    assert not (tmp_path / "r.html").exists()
