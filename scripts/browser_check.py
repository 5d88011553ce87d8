#!/usr/bin/env python3
"""Open ggs's HTML reports in headless Chromium and check what a person would see.

For every report given: the page loads from disk with no console error, no uncaught script
error and no request other than the file itself and its inline data: URLs; every picture
(`img`, `canvas`, inline `svg` charts) is not blank (at least 1 % of its pixels differ from the white background);
in a registration report, the 3-D view's "show before" button changes the canvas. Prints the
file size and the load time; `--screenshots DIR` also saves a full-page screenshot of each.

Needs Debian's chromium (/usr/bin/chromium) and the PyPI packages playwright and pillow
(`.ci/run` installs them). Exit status 1 if any check fails.

    python3 scripts/browser_check.py out/report.html run/report.html --screenshots shots/
"""

import argparse
import io
import pathlib
import sys
import time

from PIL import Image, ImageChops
from playwright.sync_api import sync_playwright

CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def painted_fraction(png: bytes) -> float:
    """Share of pixels that differ from white by more than 30 in some channel."""
    r, g, b = Image.open(io.BytesIO(png)).convert("RGB").split()
    darkest = ImageChops.darker(ImageChops.darker(r, g), b).histogram()
    return sum(darkest[:225]) / max(1, sum(darkest))


def check(page, path: pathlib.Path, shots) -> list:
    problems, requests = [], []
    page.on("console", lambda m: m.type == "error" and problems.append(f"console error: {m.text}"))
    page.on("pageerror", lambda e: problems.append(f"script error: {e}"))
    page.on("request", lambda r: requests.append(r.url))
    url = path.resolve().as_uri()
    t0 = time.perf_counter()
    page.goto(url, wait_until="load")
    load_s = time.perf_counter() - t0
    for r in requests:
        if r != url and not r.startswith("data:"):
            problems.append(f"network request: {r}")
    pictures = page.query_selector_all("img, canvas, svg")
    if not pictures:
        problems.append("no picture on the page")
    for k, el in enumerate(pictures):
        el.scroll_into_view_if_needed()
        frac = painted_fraction(el.screenshot())
        if frac < 0.01:
            problems.append(f"picture {k} ({el.get_attribute('alt') or 'canvas'}) is blank: {frac:.4f}")
    toggle = page.query_selector("#ggs-toggle")
    if toggle is not None:
        canvas = page.query_selector("#ggs-viewer")
        before = canvas.screenshot()
        toggle.click()
        if canvas.screenshot() == before:
            problems.append("the 3-D view did not change on 'show before'")
        toggle.click()
    if shots is not None:
        shots.mkdir(parents=True, exist_ok=True)
        name = f"{path.parent.name}-{path.stem}.png"
        page.screenshot(path=str(shots / name), full_page=True)
    size = path.stat().st_size / 1e6
    print(f"{path}: {size:.2f} MB, loaded in {load_s:.2f} s, {len(pictures)} pictures, "
          f"{len(problems)} problem(s)")
    return problems


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("reports", nargs="+", type=pathlib.Path)
    ap.add_argument("--screenshots", type=pathlib.Path)
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    args = ap.parse_args()
    failed = False
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=args.chromium, args=CHROMIUM_ARGS)
        for path in args.reports:
            if not path.is_file():
                print(f"{path}: no such file", file=sys.stderr)
                failed = True
                continue
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            for problem in check(page, path, args.screenshots):
                print(f"  {path}: {problem}", file=sys.stderr)
                failed = True
            page.close()
        browser.close()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
