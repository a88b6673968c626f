"""Shared fixtures: the real captures in ../shared/data (skipped when absent)."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"


def shared_path(*parts: str) -> Path:
    """Path inside ../shared/data; skips the calling test when it is absent."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"real data not available: {p}")
    return p


@pytest.fixture
def shared_data():
    """The ../shared/data folder (test skipped when absent)."""
    return shared_path()


def browser_screenshot(html_path: Path, png_path: Path, *, size: tuple[int, int] = (1280, 1600)) -> list[str]:
    """Render a local HTML file in headless Debian Chromium and save a screenshot.

    Returns the page's console messages (a page without scripts should have none).
    Skips the calling test when chromium is not installed.
    """
    import shutil
    import subprocess
    import tempfile

    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("chromium is not installed (make test installs Debian's chromium when run as root)")
    with tempfile.TemporaryDirectory() as profile:
        proc = subprocess.run(
            [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={profile}", "--enable-logging=stderr", "--v=0", "--hide-scrollbars",
             f"--screenshot={png_path}", f"--window-size={size[0]},{size[1]}", Path(html_path).resolve().as_uri()],
            capture_output=True, text=True, timeout=120)
    return [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]
