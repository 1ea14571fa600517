"""Helpers of the browser tests: screen positions of 3-D points, canvas pixels, panel input."""

from __future__ import annotations

import io
import time

import numpy as np
import png

from tests.ui.conftest import VIEWPORT, wait_for


def _rotation(wxyz) -> np.ndarray:
    w, x, y, z = (float(c) for c in wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def screen_of(app, xyz, viewport=None) -> tuple[int, int]:
    """Pixel of a 3-D point in the page's view (viser cameras: OpenCV axes, vertical fov);
    ``viewport`` is the page's size (default the browser tests' :data:`VIEWPORT`)."""
    (client,) = app.server.get_clients().values()
    cam = client.camera
    p = _rotation(cam.wxyz).T @ (np.asarray(xyz, float) - np.asarray(cam.position))
    view = VIEWPORT if viewport is None else viewport
    w, h = view["width"], view["height"]
    f = 0.5 * h / np.tan(0.5 * cam.fov)
    return round(f * p[0] / p[2] + 0.5 * w), round(f * p[1] / p[2] + 0.5 * h)


def canvas_pixels(page) -> np.ndarray:
    shot = page.locator("canvas").nth(1).screenshot()
    w, h, rows, _ = png.Reader(file=io.BytesIO(shot)).asRGBA8()
    return np.vstack([np.frombuffer(r, np.uint8) for r in rows]).reshape(h, w, 4)


def changed(a: np.ndarray, b: np.ndarray) -> float:
    """Fraction of canvas pixels that differ."""
    return float((np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 8).mean())


def settle(page, seconds: float = 1.0) -> None:
    time.sleep(seconds)  # let the software renderer draw the new scene


def click_canvas(page, app, xy) -> str:
    n = len(app.messages)
    page.mouse.click(*xy)
    wait_for(lambda: len(app.messages) > n, what=f"a reply to the click at {xy}")
    return app.messages[-1]


def press(page, app, name: str, *, until=None, timeout: float = 30.0) -> str:
    """Click a panel button and wait for its reply (every button says something)."""
    n = len(app.messages)
    page.get_by_role("button", name=name, exact=True).click()
    wait_for(lambda: len(app.messages) > n, timeout=timeout, what=f"the reply to {name!r}")
    if until is not None:
        wait_for(until, what=f"the effect of {name!r}")
    return app.messages[-1]


def field(page, label: str):
    return page.locator(
        f'xpath=//label[normalize-space()="{label}"]/following::input[not(@type="hidden")][1]'
    )


def type_into(page, handle, label: str, text: str) -> None:
    box = field(page, label)
    box.fill(text)
    box.press("Enter")
    wait_for(lambda: str(handle.value) == text, what=f"{label} = {text!r}")


def choose(page, handle, label: str, option: str) -> None:
    field(page, label).click()
    page.get_by_role("option", name=option, exact=True).click()
    wait_for(lambda: handle.value == option, what=f"{label} = {option!r}")
