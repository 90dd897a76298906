"""The report of a 40,000-image output: build time and how soon the page is usable.

Writes a synthetic output folder: an annotations document (compact JSON) in the layout ``usdscene annotate``
writes (per image about 3 of 5 objects, each with a tight box, an amodal box and a polygon with their attributes,
relation text, the cross-camera table), and per image an image and a mask file. The image and
mask files are hard links to one picture and one mask of the given size, so that the folder
costs no disk while every file is still read and decoded on its own.

Then it measures:

* the first build (``usdscene.dataset.report.build_report``: the document read, index and label
  pages written, every thumbnail and mask tint drawn) and a second build (pictures kept, the
  labels part alone, e.g. after labels changed);
* in headless Chromium (Debian's ``chromium`` + ``chromium-driver``, selenium): the time from
  navigation start until the page has drawn its first grid page and its counts
  (``window.usdsceneReadyMs``), opening an image (its label page loaded on demand) and
  applying a class filter over all images.

    python benchmarks/report_scale.py [--cameras 8] [--frames 5000] [--objects 5] [--size 320x240] [--keep DIR]

Targets (issue 24): build < 60 s, page usable < 2 s. Prints each figure and its ratio to the target.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

BUILD_TARGET_S = 60.0
USABLE_TARGET_MS = 2000.0
CLASSES = ("backpack", "laptop_bag", "passenger", "trolley_suitcase", "handbag")


def synthetic_output(out: Path, cameras: int, frames: int, objects: int, width: int, height: int) -> dict:
    """Write the synthetic output folder; returns its sizes."""
    rng = np.random.default_rng(0)
    picture = np.zeros((height, width, 3), np.uint8)
    # texture so the PNG decodes like a render (flat colour would decode unrealistically fast)
    picture[:] = rng.integers(60, 200, (height, width, 3), dtype=np.uint8) // 16 * 16
    mask = np.zeros((height, width), np.uint16)
    boxes = []
    for k in range(objects):
        x0, y0 = int(rng.integers(0, width * 3 // 4)), int(rng.integers(0, height * 3 // 4))
        w, h = int(rng.integers(8, width // 4)), int(rng.integers(8, height // 4))
        mask[y0:y0 + h, x0:x0 + w] = k + 1
        boxes.append((x0, y0, w, h))
    source = out / "source"
    source.mkdir(parents=True)
    cv2.imwrite(str(source / "image.png"), picture)
    cv2.imwrite(str(source / "mask.png"), mask)
    names = [f"cam_{c:02d}" for c in range(cameras)]
    streams = {name: {"type": "camera", "stream_properties": {"intrinsics_pinhole": {
        "width_px": width, "height_px": height,
        "camera_matrix_3x4": [300.0, 0, (width - 1) / 2, 0, 0, 300.0, (height - 1) / 2, 0, 0, 0, 1, 0],
        "distortion_coeffs_1xN": []}}} for name in names}
    uids = [str(k) for k in range(objects)]
    document = {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "name": f"synthetic_{cameras * frames}_images"},
        "streams": streams,
        "objects": {uid: {"name": f"object_{uid}", "type": CLASSES[int(uid) % len(CLASSES)],
                          "frame_intervals": [{"frame_start": 0, "frame_end": frames - 1}]} for uid in uids},
        "frames": {}}}
    for camera in names:
        for folder, name in (("images", "image.png"), ("masks", "mask.png")):
            (out / folder / camera).mkdir(parents=True)
    fractions = rng.uniform(0, 1, (frames, cameras, objects)).round(6)
    present = rng.uniform(0, 1, (frames, cameras, objects)) < 0.6  # 3 of 5 objects per image on average
    for frame in range(frames):
        frame_objects = {}
        props = {"streams": {}, "usdscene": {"streams": {}}}
        for c, camera in enumerate(names):
            image_name = f"{frame:06d}.png"
            os.link(source / "image.png", out / "images" / camera / image_name)
            os.link(source / "mask.png", out / "masks" / camera / image_name)
            props["streams"][camera] = {"uri": f"images/{camera}/{image_name}"}
            props["usdscene"]["streams"][camera] = {"mask_uri": f"masks/{camera}/{image_name}", "width_px": width,
                                                    "height_px": height}
            for k, uid in enumerate(uids):
                if not present[frame, c, k]:
                    continue
                x0, y0, w, h = boxes[k]
                fraction = float(fractions[frame, c, k])
                box = [x0 + (w - 1) / 2, y0 + (h - 1) / 2, float(w), float(h)]
                attrs = {"num": [{"name": "visible_fraction", "val": fraction}, {"name": "pixel_count", "val": w * h},
                                 {"name": "mask_id", "val": k + 1}], "boolean": [{"name": "truncated", "val": False}]}
                data = frame_objects.setdefault(uid, {"object_data": {"bbox": [], "poly2d": [], "text": [
                    {"name": "resolved_place", "val": f"seat_{k:02d}A"}, {"name": "resolved_relation", "val": "is_on"}]}})
                data = data["object_data"]
                data["bbox"].append({"name": f"{camera}_bbox", "val": box, "coordinate_system": camera,
                                     "attributes": attrs})
                data["bbox"].append({"name": f"{camera}_amodal_bbox", "val": [box[0], box[1], w * 1.2, h * 1.2],
                                     "coordinate_system": camera, "attributes": attrs})
                ring = [x0, y0, x0 + w - 1, y0, x0 + w - 1, y0 + h - 1, x0 + w // 2, y0 + h + 0, x0, y0 + h - 1]
                data["poly2d"].append({"name": f"{camera}_poly2d_0", "val": [float(v) for v in ring],
                                       "mode": "MODE_POLY2D_ABSOLUTE", "closed": True, "coordinate_system": camera,
                                       "hierarchy": [-1, -1, -1, -1],
                                       "attributes": {"boolean": [{"name": "is_hole", "val": False}]}})
        document["openlabel"]["frames"][str(frame)] = {"frame_properties": props, "objects": frame_objects}
    path = out / "annotations.openlabel.json"
    # compact (usdscene writes it indented: the same content, a third larger)
    path.write_text(json.dumps(document))
    return {"images": cameras * frames, "labels": int(present.sum()), "document_mb": path.stat().st_size / 1e6}


def cpu_seconds() -> float:
    """User + system CPU seconds of this process and its threads so far."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def measure_page(index: Path) -> dict:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select, WebDriverWait

    browser_path, driver_path = shutil.which("chromium"), shutil.which("chromedriver")
    if browser_path is None or driver_path is None:
        raise SystemExit("the page figures need Debian's chromium and chromium-driver: "
                         "apt-get install chromium chromium-driver")
    options = webdriver.ChromeOptions()
    options.binary_location = browser_path
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,900"):
        options.add_argument(flag)
    browser = webdriver.Chrome(service=Service(driver_path), options=options)
    try:
        figures = {}
        for attempt in range(2):  # the first load also warms the browser's disk cache
            browser.get(index.as_uri())
            WebDriverWait(browser, 60).until(lambda b: b.execute_script("return document.body.dataset.ready === '1'"))
            figures[f"usable_ms_{attempt}"] = browser.execute_script("return window.usdsceneReadyMs")
        t = time.perf_counter()
        cells = browser.find_elements(By.CSS_SELECTOR, "#grid .cell")
        cells[len(cells) // 2].click()
        WebDriverWait(browser, 30).until(lambda b: b.find_element(By.ID, "viewer").is_displayed())
        figures["open_image_ms"] = 1000 * (time.perf_counter() - t)
        browser.find_element(By.ID, "viewer-close").click()
        t = time.perf_counter()
        Select(browser.find_element(By.ID, "f-class")).select_by_visible_text("handbag")
        WebDriverWait(browser, 30).until(lambda b: "images match" in b.find_element(By.ID, "f-count").text)
        figures["filter_ms"] = 1000 * (time.perf_counter() - t)
        figures["filter_text"] = browser.find_element(By.ID, "f-count").text
        figures["errors"] = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
        return figures
    finally:
        browser.quit()


def main() -> None:
    from usdscene.dataset.report import build_report

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cameras", type=int, default=8)
    parser.add_argument("--frames", type=int, default=5000)
    parser.add_argument("--objects", type=int, default=5)
    parser.add_argument("--size", default="320x240", help="image size WxH (the cabin example's is 320x240)")
    parser.add_argument("--keep", type=Path, help="write the folder here and keep it")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    root = args.keep or Path(tempfile.mkdtemp(prefix="report_scale_"))
    try:
        out = root / "out"
        t = time.perf_counter()
        sizes = synthetic_output(out, args.cameras, args.frames, args.objects, width, height)
        print(f"synthetic output: {sizes['images']} images {width}x{height}, {sizes['labels']} labels, "
              f"document {sizes['document_mb']:.0f} MB (written in {time.perf_counter() - t:.0f} s)")
        cpu = cpu_seconds()
        first = build_report(out)
        cpu, first_cpu = cpu_seconds(), cpu_seconds() - cpu
        print(f"first build:  {first.seconds:6.1f} s wall, {first_cpu:.1f} s CPU ({first.pictures_drawn} thumbnails "
              f"and mask tints drawn; {1000 * first.seconds / first.images:.2f} ms per image)  / target "
              f"{BUILD_TARGET_S:.0f} s = {first.seconds / BUILD_TARGET_S:.2f}")
        second = build_report(out)
        print(f"second build: {second.seconds:6.1f} s wall, {cpu_seconds() - cpu:.1f} s CPU (pictures kept: the "
              f"labels part)  / target = {second.seconds / BUILD_TARGET_S:.2f}")
        print(f"load average while measuring: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        data = out / "report" / "data"
        pages = sorted(data.glob("labels_*.js"))
        print(f"index.js {(data / 'index.js').stat().st_size / 1e6:.2f} MB loaded at once; {len(pages)} label pages of "
              f"{np.mean([p.stat().st_size for p in pages]) / 1e3:.0f} kB loaded on demand")
        page = measure_page(first.index)
        print(f"page usable:  {page['usable_ms_0']:.0f} ms cold, {page['usable_ms_1']:.0f} ms warm  / target "
              f"{USABLE_TARGET_MS:.0f} ms = {page['usable_ms_0'] / USABLE_TARGET_MS:.2f} / "
              f"{page['usable_ms_1'] / USABLE_TARGET_MS:.2f}")
        print(f"open an image (label page on demand): {page['open_image_ms']:.0f} ms; class filter over every image: "
              f"{page['filter_ms']:.0f} ms ({page['filter_text']}); console errors: {len(page['errors'])}")
    finally:
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
