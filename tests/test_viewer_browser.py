"""The meshcat page in a real browser (Debian's Chromium via Playwright): it draws the
wrist, the picture changes when the pose changes, and the planned path shows.
Screenshots are saved under ``artifacts/``."""

from __future__ import annotations

import io
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = Path(__file__).resolve().parent.parent / "artifacts"
pytestmark = pytest.mark.skipif(not CHROMIUM.exists(), reason="/usr/bin/chromium is absent")

ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
#: The legs' colours in the view (red, blue, yellow), RGB.
LEG_RGB = [(0xD1, 0x49, 0x5B), (0x2E, 0x86, 0xAB), (0xED, 0xAE, 0x49)]
PATH_RGB = (0xFF, 0x00, 0xFF)


def _pixels(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


def _mask(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 60) -> np.ndarray:
    """Pixels of about this hue (shading darkens them: compare the colour direction too)."""
    ref = np.asarray(rgb, float)
    f = img.astype(float)
    n = np.linalg.norm(f, axis=-1) + 1e-9
    cos = (f @ ref) / (n * np.linalg.norm(ref))
    return np.asarray((cos > 0.985) & (np.abs(f - ref).max(-1) < 3 * tol))


@pytest.fixture
def view(agile) -> Iterator:  # type: ignore[no-untyped-def]
    from spm_console.viewer.view import MeshcatView

    v = MeshcatView(agile, min_interval_s=0.05)
    v.start()
    yield v
    v.close()


@pytest.fixture
def page(view) -> Iterator:  # type: ignore[no-untyped-def]
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        pg = browser.new_page(viewport={"width": 800, "height": 600})
        pg.goto(view.url)
        pg.wait_for_selector("canvas", timeout=20_000)
        yield pg
        browser.close()


def _settled_shot(page, name: str, timeout_s: float = 20.0) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Screenshot once two consecutive frames agree (the scene has arrived and rendered)."""
    t_end = time.monotonic() + timeout_s
    last = _pixels(page.screenshot())
    while time.monotonic() < t_end:
        time.sleep(0.4)
        img = _pixels(page.screenshot())
        legs = sum(int(_mask(img, c).sum()) for c in LEG_RGB)
        if legs > 500 and np.abs(img - last).max(-1).mean() < 0.5:
            break
        last = img
    ARTIFACTS.mkdir(exist_ok=True)
    from PIL import Image

    Image.fromarray(img.astype(np.uint8)).save(ARTIFACTS / f"viewer-{name}.png")
    return img


def test_page_draws_the_wrist_and_follows_the_pose(view, page) -> None:  # type: ignore[no-untyped-def]
    home = _settled_shot(page, "home")
    counts = [int(_mask(home, c).sum()) for c in LEG_RGB]
    assert all(n > 150 for n in counts), f"leg pixels per colour {counts}: wrist not drawn"
    # loopback only: the page came from 127.0.0.1
    assert view.url.startswith("http://127.0.0.1:")

    view.show_theta(np.array([95.0, 110.0, 105.0]))  # the paper's eq. (32) pose
    assert view.wait_idle(10.0) and not view.last_error
    np.testing.assert_allclose(view.drawn_theta_deg, [95, 110, 105])
    moved = _settled_shot(page, "theta-95-110-105")
    changed = float((np.abs(moved - home).max(-1) > 30).mean())
    assert changed > 0.01, f"only {changed:.2%} of the picture changed"
    # the legs moved: the centroid of at least one leg's colour shifted by several pixels
    shifts = []
    for c in LEG_RGB:
        a, b = np.argwhere(_mask(home, c)), np.argwhere(_mask(moved, c))
        shifts.append(float(np.linalg.norm(a.mean(0) - b.mean(0))))
    assert max(shifts) > 5.0, shifts


def test_planned_path_is_previewed(view, page) -> None:  # type: ignore[no-untyped-def]
    before = _settled_shot(page, "before-path")
    assert int(_mask(before, PATH_RGB).sum()) == 0
    path = np.linspace([135.0, 135.0, 135.0], [95.0, 110.0, 105.0], 60)
    view.show_path(path)
    assert view.wait_idle(10.0) and not view.last_error
    after = _settled_shot(page, "path")
    assert int(_mask(after, PATH_RGB).sum()) > 20
