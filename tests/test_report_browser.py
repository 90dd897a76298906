"""The report of the minimal example in a real browser: headless Chromium (Debian's
``chromium`` and ``chromium-driver``) driven by selenium, one browser for the whole module.

The page is opened from ``file://`` as a person would open it: no server, no network."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from usdscene.cli import main

REPO = Path(__file__).resolve().parent.parent
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"

pytestmark = [pytest.mark.blender, pytest.mark.slow]


def _chromium() -> tuple[str, str]:
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if not browser or not driver:
        pytest.fail("the browser tests need Debian's chromium and chromium-driver "
                    "(apt-get install chromium chromium-driver; .ci/run installs them)")
    return browser, driver


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """The minimal example run tiny (2 frames, 1 sample); ``usdscene run`` writes the report."""
    out = tmp_path_factory.mktemp("report") / "out"
    assert main(["run", str(MINIMAL), "-o", str(out), "--frames", "0:1", "--samples", "1", "--export",
                 "--no-progress"]) == 0
    assert (out / "report" / "index.html").is_file()
    return out


@pytest.fixture(scope="module")
def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    binary, driver = _chromium()
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,900",
                 "--disable-gpu", "--no-first-run"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    session = webdriver.Chrome(service=Service(driver), options=options)
    try:
        yield session
    finally:
        session.quit()


def _visible(browser, selector: str) -> list:
    return [e for e in browser.find_elements("css selector", selector) if e.is_displayed()]


def _labels(out: Path) -> dict[tuple[int, str], list[dict]]:
    """(frame, camera) → labels of the annotations document (what the page must show)."""
    from usdscene.converters.openlabel.annotations import LabelIndex, image_records

    document = json.loads((out / "annotations.openlabel.json").read_text())
    index = LabelIndex(document)
    return {(r["frame"], r["camera"]): index.labels(r["frame"], r["camera"]) for r in image_records(document)}


def test_report_in_chromium(report, browser, tmp_path):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import Select, WebDriverWait

    labels = _labels(report)
    shots = tmp_path / "screenshots"
    shots.mkdir()
    browser.get((report / "report" / "index.html").as_uri())
    WebDriverWait(browser, 20).until(lambda b: b.execute_script("return document.body.dataset.ready === '1'"))

    # The grid: one row per frame, one column per camera, every thumbnail decoded.
    assert [th.text for th in browser.find_elements(By.CSS_SELECTOR, "#grid thead th")] == ["frame", "cam_01", "cam_02"]
    assert [td.text for td in browser.find_elements(By.CSS_SELECTOR, "#grid td.frame")] == ["0", "1"]
    cells = browser.find_elements(By.CSS_SELECTOR, "#grid .cell")
    assert len(cells) == len(labels) == 4
    WebDriverWait(browser, 10).until(lambda b: b.execute_script(
        "return [...document.querySelectorAll('#grid img')].every(i => i.complete && i.naturalWidth > 0)"))
    visible_per_camera = {}
    for (frame, camera), image_labels in labels.items():
        visible_per_camera[camera] = visible_per_camera.get(camera, 0) + sum(1 for o in image_labels if o["bbox"])
    rows = browser.find_elements(By.CSS_SELECTOR, "#camera-counts tbody tr")
    assert {r.find_elements(By.TAG_NAME, "td")[0].text: int(r.find_elements(By.TAG_NAME, "td")[2].text)
            for r in rows} == visible_per_camera
    browser.save_screenshot(str(shots / "grid.png"))

    # Keyboard in the grid: ↓ from frame 0 of cam_01 to frame 1, Enter opens it.
    browser.find_element(By.CSS_SELECTOR, '#grid .cell[title="cam_01 · frame 0"]').send_keys(Keys.ARROW_DOWN)
    focused = browser.switch_to.active_element
    assert focused.get_attribute("title") == "cam_01 · frame 1"
    # The image view of frame 1, cam_01: one tight box per visible label, the rest toggled on.
    focused.send_keys(Keys.ENTER)
    WebDriverWait(browser, 10).until(lambda b: b.find_element(By.ID, "viewer").is_displayed())
    expected = labels[(1, "cam_01")]
    assert browser.find_element(By.ID, "viewer-title").text.startswith("cam_01 · frame 1")
    assert len(_visible(browser, "#canvas rect.ov-box")) == sum(1 for o in expected if o["bbox"])
    assert not _visible(browser, "#canvas rect.ov-amodal")
    browser.find_element(By.CSS_SELECTOR, 'input[data-overlay="amodal"]').click()
    assert len(_visible(browser, "#canvas rect.ov-amodal")) == sum(1 for o in expected if o["amodal_bbox"])
    browser.find_element(By.TAG_NAME, "body").send_keys("4")  # key 4: the mask tint
    assert browser.find_element(By.CSS_SELECTOR, 'input[data-overlay="tint"]').is_selected()
    assert _visible(browser, "#canvas image.ov-tint")
    texts = [t.text for t in browser.find_elements(By.CSS_SELECTOR, "#canvas text.ov-text")]
    assert any("is_below seat_01A" in t for t in texts), texts  # the relation of the backpack
    browser.save_screenshot(str(shots / "view.png"))
    browser.find_element(By.CSS_SELECTOR, 'input[data-overlay="box"]').click()
    assert not _visible(browser, "#canvas rect.ov-box")

    # Keyboard: → is the next frame of the same camera, ↓ the next camera, Esc closes.
    browser.find_element(By.TAG_NAME, "body").send_keys(Keys.ARROW_LEFT)
    WebDriverWait(browser, 5).until(
        lambda b: b.find_element(By.ID, "viewer-title").text.startswith("cam_01 · frame 0"))
    browser.find_element(By.TAG_NAME, "body").send_keys(Keys.ARROW_DOWN)
    WebDriverWait(browser, 5).until(
        lambda b: b.find_element(By.ID, "viewer-title").text.startswith("cam_02 · frame 0"))
    browser.find_element(By.TAG_NAME, "body").send_keys(Keys.ESCAPE)
    assert not browser.find_element(By.ID, "viewer").is_displayed()

    # A class filter keeps the images that show a laptop (visible or not) and dims the rest.
    Select(browser.find_element(By.ID, "f-class")).select_by_visible_text("laptop")
    with_laptop = sum(1 for image_labels in labels.values() if any(o["type"] == "laptop" for o in image_labels))
    assert 0 < with_laptop < len(labels)
    assert browser.find_element(By.ID, "f-count").text == f"{with_laptop} of {len(labels)} images match"
    assert len(browser.find_elements(By.CSS_SELECTOR, "#grid td:not(.filtered) .cell")) == with_laptop
    browser.save_screenshot(str(shots / "filtered.png"))
    for name in ("grid.png", "view.png", "filtered.png"):
        assert (shots / name).stat().st_size > 1000

    errors = [entry for entry in browser.get_log("browser") if entry["level"] == "SEVERE"]
    assert errors == [], errors


def test_image_labelled_with_nothing_opens_without_a_tint(report, browser, tmp_path):
    """An image whose mask is all background has no tint file: the page must not ask for one
    (from ``file://`` a missing file is a console error) and still draws the image."""
    import cv2
    import numpy as np
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import WebDriverWait

    from usdscene.dataset.report_pictures import picture_paths

    out = tmp_path / "out"
    shutil.copytree(report, out)
    mask = out / "masks" / "cam_02" / "000001.png"
    height, width = cv2.imread(str(mask), cv2.IMREAD_UNCHANGED).shape
    cv2.imwrite(str(mask), np.zeros((height, width), np.uint16))
    annotations = out / "annotations.openlabel.json"
    document = json.loads(annotations.read_text())
    for entry in document["openlabel"]["frames"]["1"]["objects"].values():
        data = entry.get("object_data", {})
        for kind, items in list(data.items()):
            if isinstance(items, list):
                data[kind] = [item for item in items if not str(item.get("name", "")).startswith("cam_02_")]
    annotations.write_text(json.dumps(document))
    shutil.rmtree(out / "report")
    assert main(["report", str(out)]) == 0
    assert not picture_paths(out / "report", "cam_02", 1)[1].exists()
    assert picture_paths(out / "report", "cam_01", 1)[1].is_file()

    browser.get_log("browser")  # drop what earlier pages logged
    browser.get((out / "report" / "index.html").as_uri())
    WebDriverWait(browser, 20).until(lambda b: b.execute_script("return document.body.dataset.ready === '1'"))
    browser.find_element(By.CSS_SELECTOR, '#grid .cell[title="cam_02 · frame 1"]').send_keys(Keys.ENTER)
    WebDriverWait(browser, 10).until(lambda b: b.find_element(By.ID, "viewer").is_displayed())
    assert browser.find_element(By.ID, "viewer-title").text.startswith("cam_02 · frame 1")
    tint_toggle = browser.find_element(By.CSS_SELECTOR, 'input[data-overlay="tint"]')
    if not tint_toggle.is_selected():
        browser.find_element(By.TAG_NAME, "body").send_keys("4")
    assert tint_toggle.is_selected()
    assert _visible(browser, "#canvas image.photo")
    assert not browser.find_elements(By.CSS_SELECTOR, "#canvas image.ov-tint")
    assert not _visible(browser, "#canvas rect.ov-box")
    # The neighbouring image of the same frame still has its tint.
    browser.find_element(By.TAG_NAME, "body").send_keys(Keys.ARROW_UP)
    WebDriverWait(browser, 5).until(
        lambda b: b.find_element(By.ID, "viewer-title").text.startswith("cam_01 · frame 1"))
    assert _visible(browser, "#canvas image.ov-tint")
    errors = [entry for entry in browser.get_log("browser") if entry["level"] == "SEVERE"]
    assert errors == [], errors
