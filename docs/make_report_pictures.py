"""Screenshots of the report of a ``usdscene run`` output for the quickstart, taken in headless
Chromium (Debian's ``chromium`` and ``chromium-driver``, driven by selenium from the test extra).

Writes into ``docs/img/``:

* ``report_grid.png`` — the page as it opens: camera × frame thumbnails, per-camera counts,
  visibility histogram, labels per class;
* ``report_view.png`` — one image opened with tight boxes, amodal boxes, polygons, mask tint and
  the label text switched on.

Usage::

    usdscene run examples/aircraft_cabin/cabin.openlabel.json -o out/
    python docs/make_report_pictures.py out/ [--camera seats_L03] [--frame 0]
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

IMG = Path(__file__).resolve().parent / "img"


def main() -> None:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path)
    parser.add_argument("--camera", default="seats_L03")
    parser.add_argument("--frame", type=int, default=0)
    args = parser.parse_args()
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,900"):
        options.add_argument(flag)
    browser = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    try:
        browser.get((args.output / "report" / "index.html").resolve().as_uri())
        WebDriverWait(browser, 30).until(lambda b: b.execute_script("return document.body.dataset.ready === '1'"))
        WebDriverWait(browser, 30).until(lambda b: b.execute_script(
            "return [...document.querySelectorAll('#grid img')]"  # lazy: those in view
            ".filter(i => { const r = i.getBoundingClientRect(); return r.top < innerHeight && r.left < innerWidth; })"
            ".every(i => i.complete)"))
        browser.save_screenshot(str(IMG / "report_grid.png"))
        browser.find_element(By.CSS_SELECTOR, f'#grid .cell[title="{args.camera} · frame {args.frame}"]').click()
        WebDriverWait(browser, 30).until(lambda b: b.find_element(By.ID, "viewer").is_displayed())
        for overlay in ("amodal", "tint"):
            browser.find_element(By.CSS_SELECTOR, f'input[data-overlay="{overlay}"]').click()
        browser.execute_script("return new Promise(r => setTimeout(r, 500))")
        browser.save_screenshot(str(IMG / "report_view.png"))
    finally:
        browser.quit()
    print(f"wrote {IMG / 'report_grid.png'} and {IMG / 'report_view.png'}")


if __name__ == "__main__":
    main()
