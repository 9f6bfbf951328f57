"""The meshcat page in a real browser (Debian's Chromium via Playwright): nothing solid
before a measurement, the measured wrist solid and following the measurements, a target
as a translucent ghost that never moves the measured wrist, the planned path, labels.
Screenshots are saved under ``artifacts/``."""

from __future__ import annotations

import io
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from spm_console.viewer import draw
from tests.support.paths import ROOT as PROJECT_ROOT

CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = PROJECT_ROOT / "artifacts"
pytestmark = pytest.mark.skipif(not CHROMIUM.exists(), reason="/usr/bin/chromium is absent")

ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
#: The legs' colours in the view (red, blue, yellow), RGB.
LEG_RGB = [((c >> 16) & 255, (c >> 8) & 255, c & 255) for c in draw.LEG_COLORS]
PATH_RGB = (0xFF, 0x00, 0xFF)
HOME = np.array([135.0, 135.0, 135.0])
GOAL = np.array([95.0, 110.0, 105.0])  # the paper's eq. (32) pose


def _pixels(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


def _mask(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 60) -> np.ndarray:
    """Pixels of this opaque colour. Shading scales a colour (white lights): same direction,
    same saturation. A translucent veil over the light background is paler: less saturated."""
    ref = np.asarray(rgb, float)
    f = img.astype(float)
    n = np.linalg.norm(f, axis=-1) + 1e-9
    cos = (f @ ref) / (n * np.linalg.norm(ref))
    sat = (f.max(-1) - f.min(-1)) / (f.max(-1) + 1e-9)
    ref_sat = (ref.max() - ref.min()) / ref.max()
    return np.asarray((cos > 0.985) & (np.abs(f - ref).max(-1) < 3 * tol)
                      & (sat > 0.85 * ref_sat))


def _solid(img: np.ndarray) -> np.ndarray:
    """Pixels in one of the legs' own (opaque) colours."""
    return np.asarray(np.logical_or.reduce([_mask(img, c) for c in LEG_RGB]))


def _dilate(mask: np.ndarray, r: int) -> np.ndarray:
    out = mask.copy()
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out |= np.roll(np.roll(mask, dy, 0), dx, 1)
    return out


def _changed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.asarray(np.abs(a - b).max(-1) > 25)


@pytest.fixture
def view(agile) -> Iterator[Any]:  # type: ignore[no-untyped-def]
    from spm_console.viewer.view import MeshcatView

    v = MeshcatView(agile, min_interval_s=0.05)
    v.start()
    yield v
    v.close()


@pytest.fixture
def page(view) -> Iterator[Any]:  # type: ignore[no-untyped-def]
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        pg = browser.new_page(viewport={"width": 800, "height": 600})
        pg.goto(view.url)
        pg.wait_for_selector("canvas", timeout=20_000)
        yield pg
        browser.close()


def _shot(page: Any, name: str, until: Callable[[np.ndarray], bool],
          timeout_s: float = 20.0) -> np.ndarray:
    """Screenshot once ``until`` holds and two consecutive frames agree (arrived, rendered)."""
    t_end = time.monotonic() + timeout_s
    last = _pixels(page.screenshot())
    while True:
        time.sleep(0.3)
        img = _pixels(page.screenshot())
        settled = until(img) and np.abs(img - last).max(-1).mean() < 0.5
        if settled or time.monotonic() > t_end:
            break
        last = img
    ARTIFACTS.mkdir(exist_ok=True)
    from PIL import Image

    Image.fromarray(img.astype(np.uint8)).save(ARTIFACTS / f"viewer-{name}.png")
    return img


def _scene(page: Any, *path: str) -> dict[str, Any]:
    """Visibility (with its parents') and material of one node of the page's three.js scene."""
    return dict(page.evaluate(
        """(path) => {
            let node = viewer.scene_tree.find(path), o = node.object, shown = true;
            for (let p = o; p; p = p.parent) shown = shown && p.visible;
            let m = o.material || {};
            return {shown: shown, opacity: m.opacity, transparent: m.transparent,
                    matrix: Array.from(o.matrixWorld.elements)};
        }""", list(path)))


def _drawn(view: Any) -> None:
    assert view.wait_idle(10.0) and not view.last_error, view.last_error


def test_nothing_solid_before_a_measurement_then_the_wrist_follows(view, page) -> None:  # type: ignore[no-untyped-def]
    # loopback only: the page came from 127.0.0.1
    assert view.url.startswith("http://127.0.0.1:")
    unknown = _shot(page, "unknown", lambda img: True)
    assert int(_solid(unknown).sum()) < 30, "a wrist is drawn before any measurement"
    assert _scene(page, "meshcat", "labels", "unknown", "<object>")["shown"]

    view.show_theta(HOME)
    _drawn(view)
    home = _shot(page, "home", lambda img: int(_solid(img).sum()) > 500)
    counts = [int(_mask(home, c).sum()) for c in LEG_RGB]
    assert all(n > 150 for n in counts), f"leg pixels per colour {counts}: wrist not drawn"
    assert not _scene(page, "meshcat", "labels", "unknown", "<object>")["shown"]
    for i in (1, 2, 3):  # the leg labels stay
        assert _scene(page, "meshcat", "labels", f"leg{i}", "<object>")["shown"]

    view.show_theta(GOAL)
    _drawn(view)
    np.testing.assert_allclose(view.drawn_theta_deg, GOAL)
    moved = _shot(page, "measured-95-110-105",
                  lambda img: float(_changed(img, home).mean()) > 0.01)
    # the legs moved: the centroid of at least one leg's colour shifted by several pixels
    shifts = []
    for c in LEG_RGB:
        a, b = np.argwhere(_mask(home, c)), np.argwhere(_mask(moved, c))
        shifts.append(float(np.linalg.norm(a.mean(0) - b.mean(0))))
    assert max(shifts) > 5.0, shifts


def test_target_is_a_ghost_and_never_moves_the_measured_wrist(view, page) -> None:  # type: ignore[no-untyped-def]
    view.show_theta(HOME)
    _drawn(view)
    home = _shot(page, "measured-home", lambda img: int(_solid(img).sum()) > 500)
    solid_home = _solid(home)
    body = ("legs", "leg1", "AB", "body", "<object>")
    measured, ghost = _scene(page, "meshcat", "measured", *body), \
        _scene(page, "meshcat", "target", *body)
    assert measured["shown"] and measured["opacity"] == 1 and not measured["transparent"]
    assert not ghost["shown"]  # no target yet
    assert ghost["transparent"] and ghost["opacity"] == pytest.approx(draw.GHOST_OPACITY)

    view.show_target(GOAL)
    _drawn(view)
    both = _shot(page, "measured-home-target-95-110-105",
                 lambda img: int((_changed(img, home) & ~_solid(img)).sum()) > 500)
    ghost_px = _changed(both, home) & ~_solid(both)
    assert int(ghost_px.sum()) > 500, "the ghost is not drawn"
    # the ghost is not drawn in the legs' solid colours: translucent over the background
    assert int((_solid(both) & ~_dilate(solid_home, 2)).sum()) < 40, \
        "solid leg pixels appeared where the measured wrist is not: it moved"
    assert int(_solid(both).sum()) > 0.6 * int(solid_home.sum()), \
        "the measured wrist lost most of its pixels"
    measured2 = _scene(page, "meshcat", "measured", *body)
    ghost2 = _scene(page, "meshcat", "target", *body)
    assert measured2["matrix"] == measured["matrix"] and ghost2["shown"]
    assert not np.allclose(ghost2["matrix"], measured2["matrix"], atol=1e-3)
    np.testing.assert_allclose(view.drawn_theta_deg, HOME)
    np.testing.assert_allclose(view.target_theta_deg, GOAL)

    view.show_target(None)
    _drawn(view)
    cleared = _shot(page, "target-cleared",
                    lambda img: float(_changed(img, home).mean()) < 0.001)
    assert float(_changed(cleared, home).mean()) < 0.001, "the ghost did not go away"


def test_plan_shows_its_path_and_goal_as_ghost_beside_the_measured_wrist(view, page) -> None:  # type: ignore[no-untyped-def]
    view.show_theta(HOME)
    _drawn(view)
    before = _shot(page, "before-plan", lambda img: int(_solid(img).sum()) > 500)
    assert int(_mask(before, PATH_RGB).sum()) == 0
    path = np.linspace(HOME, GOAL, 60)
    view.show_plan(path)
    _drawn(view)
    after = _shot(page, "plan", lambda img: int(_mask(img, PATH_RGB).sum()) > 20)
    assert int(_mask(after, PATH_RGB).sum()) > 20, "the path is not drawn"
    assert int((_changed(after, before) & ~_solid(after)).sum()) > 500, "no ghost at the goal"
    assert int((_solid(after) & ~_dilate(_solid(before), 2)).sum()) < 40
    np.testing.assert_allclose(view.drawn_theta_deg, HOME)
    np.testing.assert_allclose(view.target_theta_deg, GOAL)
    assert view.path_rows == len(path)
