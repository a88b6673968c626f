"""The interactive light-field page (issue 19, item 5): ``plenodecode export LF -o page.html --format html``.

Two textured planes at known disparities (``tests/render/test_refocus.py::two_planes``) are exported through the
CLI; headless Chromium, driven through the DevTools protocol on ``--remote-debugging-pipe`` (standard library
only), clicks on each plane and drags the photograph; the page must show the slice whose slope is nearest to the
plane's disparity and the view nearest to the drag, without console errors.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import os
import re
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from tests.conftest import browser_screenshot
from tests.render.test_refocus import two_planes

from plenodecode.cli.main import cli
from plenodecode.errors import FormatError
from plenodecode.io.lightfield import detect_format, load_lightfield, save_lightfield
from plenodecode.report.lightfield_page import (DEFAULT_SLICES, lightfield_page_data, stack_alphas, stack_slopes,
                                                view_subset)

D_BG, D_FG = -0.6, 0.8                 # disparities of the background and of the rectangle (px per view step)
RECT = (18, 46, 48, 80)                # the rectangle in the centre view: rows y0:y1, columns x0:x1
SHAPE = (64, 88)
WINDOW = (1200, 900)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """The page of the two-plane light field (9 x 9 views of 64 x 88), written by the CLI from a Zarr store."""
    folder = tmp_path_factory.mktemp("page")
    lf, _ = two_planes(n=9, shape=SHAPE, d_bg=D_BG, d_fg=D_FG, rect=RECT)
    src = save_lightfield(lf, folder / "planes.zarr")
    out = folder / "planes.html"
    res = CliRunner().invoke(cli, ["export", str(src), "-o", str(out), "--format", "html"])
    assert res.exit_code == 0, res.output
    assert "wrote" in res.output and out.is_file()
    html = out.read_text(encoding="utf-8")
    data = json.loads(re.search(r'<script type="application/json" id="lf-data">(.*?)</script>', html, re.S).group(1))
    return {"path": out, "html": html, "data": data, "lf": lf}


# ------------------------------------------------------------------------------------------ the file
def test_page_is_one_self_contained_file(page):
    html, data = page["html"], page["data"]
    # nothing from outside: every src/href is a data: URI, no external script, style, font or fetch
    assert re.findall(r'(?:src|href)\s*=\s*"(?!data:)', html) == []
    assert not re.search(r"https?://|@import|url\(|fetch\(|XMLHttpRequest", html)
    assert len(data["slices"]) == DEFAULT_SLICES and len(data["slopes"]) == DEFAULT_SLICES
    assert [(v["v"], v["u"]) for v in data["views"]] == [(v, u) for v in range(2, 7) for u in range(2, 7)]
    # the slopes span the scene's disparities (lf.geometry.disparity_range, widened)
    slopes = np.array(data["slopes"])
    assert np.all(np.diff(slopes) > 0) and slopes[0] < D_BG and slopes[-1] > D_FG
    # 8-bit JPEG photographs and views, PNG depth map, all decodable at the light field's size
    import cv2

    for uri, magic in [(data["slices"][0], b"\xff\xd8\xff"), (data["views"][0]["src"], b"\xff\xd8\xff"),
                       (data["depth"]["src"], b"\x89PNG")]:
        raw = base64.b64decode(uri.split(",", 1)[1])
        assert raw.startswith(magic)
        img = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_UNCHANGED)
        assert img.dtype == np.uint8 and img.shape[:2] == SHAPE
    # the embedded disparity map separates the two planes (what a click reads)
    depth = data["depth"]
    disp = np.frombuffer(base64.b64decode(depth["values"]), "<f4").reshape(depth["height"], depth["width"])
    assert abs(np.median(disp[RECT[0] + 4:RECT[1] - 4, RECT[2] + 4:RECT[3] - 4]) - D_FG) < 0.05
    assert abs(np.median(disp[20:44, 6:30]) - D_BG) < 0.05
    # the colour state in words, as info and decode say it ('3 channels, colour linear-srgb' was the identifier)
    said = re.findall(r"in \d+ slices;[^<]*", html)
    assert said == [f"in {DEFAULT_SLICES} slices; 64&times;88 px, linear sRGB."], said


def test_slopes_fall_back_on_the_depth_map_and_alpha_needs_the_camera():
    lf, truth = two_planes(n=5, shape=SHAPE, d_bg=D_BG, d_fg=D_FG, rect=RECT)
    bare = lf.replace(metadata={})                      # no disparity range, no camera constants
    slopes = stack_slopes(bare, truth, 9)
    pad = 0.1 * (D_FG - D_BG) + 0.05
    np.testing.assert_allclose([slopes[0], slopes[-1]], [D_BG - pad, D_FG + pad], atol=1e-6)
    assert stack_alphas(bare, slopes) is None


def test_alpha_of_each_slope_inverts_alpha_to_slope():
    from plenodecode.render import alpha_to_slope

    lf, _ = two_planes(n=5, shape=(30, 40))
    camera = {"focal_length_m": 0.0064, "f_number": 2.0, "lens_pitch_m": 1.4e-5, "spatial_step_px": 1.0,
              "view_step_px": 1.0}
    lf = lf.replace(geometry=dataclasses.replace(lf.geometry, **camera))
    slopes = np.linspace(-1, 1, 5)
    alphas = stack_alphas(lf, slopes)
    np.testing.assert_allclose(alpha_to_slope(np.array(alphas), lf), slopes, atol=1e-9)


def test_view_subset():
    assert view_subset((15, 15)) == [(v, u) for v in (3, 5, 7, 9, 11) for u in (3, 5, 7, 9, 11)]
    assert view_subset((3, 5), 5) == [(v, u) for v in (0, 1, 2) for u in (1, 2, 3)]
    assert view_subset((1, 1)) == [(0, 0)]
    with pytest.raises(ValueError, match="views"):
        view_subset((9, 9), 0)


def test_bad_parameters_are_named():
    lf, _ = two_planes(n=3, shape=(12, 14))
    for kw, name in (({"n_slices": 1}, "n_slices"), ({"depth_window": 4}, "depth_window"),
                     ({"jpeg_quality": 0}, "jpeg_quality")):
        with pytest.raises(ValueError, match=name):
            lightfield_page_data(lf, **kw)


def test_cli_picks_html_from_the_extension_and_refuses_options_of_light_fields(page, tmp_path):
    src = save_lightfield(two_planes(n=3, shape=(16, 20))[0], tmp_path / "small.zarr")
    runner = CliRunner()
    res = runner.invoke(cli, ["export", str(src), "-o", str(tmp_path / "small.html")])
    assert res.exit_code == 0, res.output
    assert "(html: 3x3 views" in res.output and (tmp_path / "small.html").read_text().startswith("<!DOCTYPE html>")
    res = runner.invoke(cli, ["export", str(src), "-o", str(tmp_path / "small.html")])
    assert res.exit_code == 2 and "--overwrite" in res.output
    res = runner.invoke(cli, ["export", str(src), "-o", str(tmp_path / "b.html"), "--srgb", "--bit-depth", "8"])
    assert res.exit_code == 2 and "--bit-depth and --srgb do not apply to the html page" in res.output
    assert not (tmp_path / "b.html").exists()
    # a page does not load back as a light field, and no light-field writer takes its name
    with pytest.raises(FormatError, match="an HTML page is an export, not a light field"):
        load_lightfield(page["path"])
    with pytest.raises(ValueError, match="not a light field"):
        detect_format(tmp_path / "new.html")
    res = runner.invoke(cli, ["export", str(page["path"]), "-o", str(tmp_path / "x.zarr")])
    assert res.exit_code == 1 and "not a light field" in res.output


# ------------------------------------------------------------------------------------------ in a browser
def test_page_renders_in_chromium(page, tmp_path):
    """Measured: 0 console lines; the screenshot has ~10000 distinct colours (the photograph and the depth map)."""
    shot = tmp_path / "page.png"
    console = browser_screenshot(page["path"], shot, size=WINDOW)
    assert console == [], console
    import cv2

    rgb = cv2.imread(str(shot), cv2.IMREAD_COLOR)
    assert rgb.shape[:2] == (WINDOW[1], WINDOW[0])
    flat = rgb.reshape(-1, 3).astype(np.int64)
    assert len(np.unique((flat[:, 0] << 16) | (flat[:, 1] << 8) | flat[:, 2])) > 2000


class DevTools:
    """Headless Chromium driven through the Chrome DevTools protocol on ``--remote-debugging-pipe``: Chromium
    reads commands on its fd 3 and writes replies and events on its fd 4, each a JSON text ended by a NUL byte."""

    def __init__(self, exe: str, profile: str, size: tuple[int, int]) -> None:
        commands_r, self._commands = os.pipe()
        self._replies, replies_w = os.pipe()

        def wire_fds() -> None:        # in the child: fds 3 and 4 (copied out of the way first: they may clash)
            import fcntl

            r = fcntl.fcntl(commands_r, fcntl.F_DUPFD, 10)
            w = fcntl.fcntl(replies_w, fcntl.F_DUPFD, 10)
            os.dup2(r, 3)
            os.dup2(w, 4)

        self.proc = subprocess.Popen(
            [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", "--hide-scrollbars", f"--user-data-dir={profile}",
             f"--window-size={size[0]},{size[1]}", "--remote-debugging-pipe", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            close_fds=False, preexec_fn=wire_fds)   # fds 3, 4 are inheritable; Python's own fds close on exec
        os.close(commands_r)
        os.close(replies_w)
        self._buffer = b""
        self._next_id = 0
        self.events: list[dict] = []
        self.session: str | None = None

    def send(self, method: str, params: dict | None = None, *, timeout: float = 30.0) -> dict:
        """Send one command (to the attached page once there is one) and return its result."""
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if self.session is not None:
            message["sessionId"] = self.session
        os.write(self._commands, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            for reply in self._read(deadline):
                if reply.get("id") == self._next_id:
                    if "error" in reply:
                        raise RuntimeError(f"{method}: {reply['error']}")
                    return reply.get("result", {})
                self.events.append(reply)

    def _read(self, deadline: float) -> list[dict]:
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([self._replies], [], [], left)[0]:
            raise TimeoutError("Chromium did not answer in time")
        chunk = os.read(self._replies, 1 << 20)
        if not chunk:
            raise RuntimeError("Chromium closed the DevTools pipe")
        self._buffer += chunk
        *messages, self._buffer = self._buffer.split(b"\0")
        return [json.loads(m) for m in messages if m]

    def open(self, url: str) -> None:
        """Attach to the page, enable the console and log events, load ``url`` and wait for the viewer."""
        pages = [t for t in self.send("Target.getTargets")["targetInfos"] if t["type"] == "page"]
        target = pages[0]["targetId"] if pages else self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Page"):
            self.send(f"{domain}.enable")
        self.send("Page.navigate", {"url": url})
        deadline = time.monotonic() + 30
        while self.evaluate("document.readyState === 'complete' && "
                            "document.getElementById('lf-viewer') !== null && "
                            "document.getElementById('lf-viewer').dataset.slice !== undefined") is not True:
            assert time.monotonic() < deadline, "the page did not load"
            time.sleep(0.1)

    def evaluate(self, expression: str):
        result = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True})
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def mouse(self, kind: str, x: float, y: float, *, held: bool = False) -> None:
        """``kind`` 'mousePressed', 'mouseReleased' (left button) or 'mouseMoved' (``held``: with the left button
        down) at viewport (x, y)."""
        params = {"type": kind, "x": x, "y": y}
        if kind != "mouseMoved":
            params.update(button="left", clickCount=1, buttons=1 if kind == "mousePressed" else 0)
        elif held:
            params.update(button="left", buttons=1)
        self.send("Input.dispatchMouseEvent", params)

    def problems(self) -> list[str]:
        """Console errors and warnings, uncaught exceptions and browser log errors seen so far."""
        out = []
        for e in self.events:
            p = e.get("params", {})
            if e.get("method") == "Runtime.consoleAPICalled" and p.get("type") in ("error", "warning", "assert"):
                out.append(f"console.{p['type']}: {[a.get('value', a.get('description')) for a in p['args']]}")
            elif e.get("method") == "Runtime.exceptionThrown":
                out.append(f"exception: {p['exceptionDetails'].get('exception', {}).get('description')}")
            elif e.get("method") == "Log.entryAdded" and p["entry"]["level"] in ("error", "warning"):
                out.append(f"log: {p['entry']['text']}")
        return out

    def close(self) -> None:
        try:
            self.session = None
            self.send("Browser.close", timeout=10)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._commands)
        os.close(self._replies)


@pytest.fixture
def browser(page):
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("chromium is not installed (make test installs Debian's chromium when run as root)")
    with tempfile.TemporaryDirectory() as profile:
        tools = DevTools(exe, profile, WINDOW)
        try:
            tools.open(page["path"].resolve().as_uri())
            yield tools
        finally:
            tools.close()


def _state(tools: DevTools) -> dict:
    return tools.evaluate("""(function () {
        var viewer = document.getElementById('lf-viewer');
        var data = JSON.parse(document.getElementById('lf-data').textContent);
        var src = document.getElementById('lf-photo').src, shown = data.slices.indexOf(src), view = -1;
        data.views.forEach(function (v, k) { if (v.src === src) view = k; });
        return {mode: viewer.dataset.mode, slice: Number(viewer.dataset.slice), view: viewer.dataset.view || null,
                shownSlice: shown, shownView: view, status: document.getElementById('lf-status').textContent};
    })()""")


def _client_point(tools: DevTools, y: float, x: float) -> tuple[float, float]:
    """Viewport coordinates of the centre of centre-view pixel (y, x) on the photograph."""
    box = tools.evaluate("(function () { var b = document.getElementById('lf-photo').getBoundingClientRect();"
                         " return [b.left, b.top, b.width, b.height]; })()")
    left, top, width, height = box
    assert width > 100 and top + height <= WINDOW[1], box          # on screen, large enough to aim at
    return left + (x + 0.5) / SHAPE[1] * width, top + (y + 0.5) / SHAPE[0] * height


def test_click_refocuses_on_each_plane(page, browser):
    slopes = np.array(page["data"]["slopes"])
    step = float(np.median(np.diff(slopes)))
    start = _state(browser)
    assert start["mode"] == "focus" and start["shownSlice"] == int(np.argmin(np.abs(slopes)))
    targets = {"rectangle": ((RECT[0] + RECT[1]) / 2, (RECT[2] + RECT[3]) / 2, D_FG), "background": (32, 18, D_BG)}
    shown = {}
    for name, (y, x, d) in targets.items():
        cx, cy = _client_point(browser, y, x)
        browser.mouse("mouseMoved", cx, cy)
        browser.mouse("mousePressed", cx, cy)
        browser.mouse("mouseReleased", cx, cy)
        st = _state(browser)
        assert st["mode"] == "focus", (name, st)
        assert st["shownSlice"] == st["slice"], (name, st)           # the photograph is that slice
        assert abs(slopes[st["slice"]] - d) <= step, (name, d, slopes[st["slice"]], st)
        assert f"slope {slopes[st['slice']]:.3f}" in st["status"], st
        shown[name] = st["slice"]
    assert shown["rectangle"] != shown["background"]
    assert browser.problems() == []


def test_drag_turns_the_viewpoint(page, browser):
    """A drag from the middle of the photograph right by half its width and down by a quarter of its height
    shows the view 2R (1/4, 1/2) = (+1, +2) views from the centre (R = 2: the subset is views 2..6 of 9)."""
    cx, cy = _client_point(browser, SHAPE[0] / 2, SHAPE[1] / 2)
    width, height = browser.evaluate("(function () { var b = document.getElementById('lf-photo')"
                                     ".getBoundingClientRect(); return [b.width, b.height]; })()")
    browser.mouse("mouseMoved", cx, cy)
    browser.mouse("mousePressed", cx, cy)
    for f in np.linspace(0.1, 1.0, 6):
        browser.mouse("mouseMoved", cx + f * width / 2, cy + f * height / 4, held=True)
    st = _state(browser)
    assert st["mode"] == "view" and st["view"] == "5,6", st
    assert page["data"]["views"][st["shownView"]]["v"] == 5 and page["data"]["views"][st["shownView"]]["u"] == 6
    browser.mouse("mouseReleased", cx + width / 2, cy + height / 4)
    assert _state(browser)["mode"] == "view"                         # releasing a drag does not refocus
    assert browser.problems() == []


def test_large_light_fields_are_reduced_to_max_side():
    """Images and the embedded disparity map share one reduced size, so a click maps to the same point."""
    import cv2

    lf, _ = two_planes(n=3, shape=SHAPE, d_bg=D_BG, d_fg=D_FG, rect=RECT)
    data = lightfield_page_data(lf, max_side=44, n_slices=4)
    depth = data["depth"]
    assert (depth["height"], depth["width"]) == (32, 44)
    for uri in (data["slices"][0], data["views"][0]["src"], depth["src"]):
        img = cv2.imdecode(np.frombuffer(base64.b64decode(uri.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
        assert img.shape[:2] == (32, 44)
    disp = np.frombuffer(base64.b64decode(depth["values"]), "<f4").reshape(32, 44)
    assert np.abs(disp[12:20, 28:36] - D_FG).max() < 0.05                # the rectangle, at its reduced place


def test_the_page_says_a_word_before_the_depth_map_and_follows_it(tmp_path, monkeypatch):
    """'export antinous -o page.html' was silent for 23 s: the progress bar appeared only after the depth map (the
    first of 3 steps).  It now starts at 0 before the depth map and moves while the depth map is estimated."""
    from plenodecode import depth

    events = []
    real = depth.estimate_depth
    monkeypatch.setattr(depth, "estimate_depth",
                        lambda *a, **k: events.append("depth") or real(*a, **k))
    lf, _ = two_planes(n=5, shape=SHAPE, d_bg=D_BG, d_fg=D_FG, rect=RECT)
    lightfield_page_data(lf, progress=lambda d, t: events.append((d, t)))
    assert events[0] == (0, 10) and events[1] == "depth", events[:3]
    during = [e for e in events[2:] if e != "depth" and e[0] < 8]
    assert len(during) >= 3 and events[-1] == (10, 10), events


def test_the_depth_legend_says_which_end_is_near(page):
    """The page's disparity legend gave two numbers and no word for which colour is near, where the depth PNGs
    mark near and far: now 'far' at the low (cold) end and 'near' at the high (warm) end, the rectangle in front
    (disparity 0.8) warm and the background (-0.6) cold in the map."""
    import base64

    import cv2

    legend = re.search(r'<div class="lf-legend"><span>(.*?)</span><span>.*?</span><span>(.*?)</span></div>',
                       page["html"].replace("&nbsp;", " ")).groups()     # each end kept on one line
    assert legend[0].startswith("far ") and legend[1].endswith(" near"), legend
    low, high = float(legend[0].split()[1]), float(legend[1].split()[0])
    assert low < 0 < high and abs(low - D_BG) < 0.15 and abs(high - D_FG) < 0.15, legend
    src = page["data"]["depth"]["src"]
    rgb = cv2.imdecode(np.frombuffer(base64.b64decode(src.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)[..., ::-1]
    warmth = rgb[..., 0].astype(int) - rgb[..., 2]
    y0, y1, x0, x1 = RECT
    assert np.median(warmth[y0 + 4:y1 - 4, x0 + 4:x1 - 4]) > 100 and np.median(warmth[:8, :8]) < -10


def test_slopes_stay_within_the_refocusable_range():
    """The page of the real F01 shoe stacked slopes -1.80 .. 0.79 where the camera refocuses -1.15 .. 1.15: the
    depth map's spread (noise, a periodic mesh) set the range, and the slices past the reach were never sharp.
    The stack now ends at the refocusable range; a scene inside it keeps its own range."""
    from plenodecode.render import refocus_range

    lf, truth = two_planes(n=5, shape=SHAPE, d_bg=D_BG, d_fg=D_FG, rect=RECT)
    g = dataclasses.replace(lf.geometry, hci=None, disparity_range=None, spatial_step_px=1.0, view_step_px=1.0,
                            calibration={"pitch": 0.4})
    plenoptic = lf.replace(geometry=g, metadata={})
    assert refocus_range(plenoptic) == pytest.approx((-0.4, 0.4))
    wide = np.where(truth > (D_BG + D_FG) / 2, 3.0, -3.0).astype(np.float32)     # a map spread past the reach
    np.testing.assert_allclose(stack_slopes(plenoptic, wide, 9), np.linspace(-0.4, 0.4, 9), atol=1e-9)
    inside = np.where(truth > (D_BG + D_FG) / 2, 0.2, -0.1).astype(np.float32)
    slopes = stack_slopes(plenoptic, inside, 9)
    pad = 0.1 * 0.3 + 0.05
    np.testing.assert_allclose([slopes[0], slopes[-1]], [-0.1 - pad, 0.2 + pad], atol=1e-6)
