"""The camera's linear chain through the real renderer (Blender Cycles, the minimal example at
64x48, 4 samples, frame 0): with every stage on the masks are the bytes of a camera without a
sensor, the same document gives the same image bytes, the exposure the camera chose is in the
annotations and --keep-clean keeps the render before the camera."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from usdscene.document import output_layout as layout

pytestmark = [pytest.mark.usd, pytest.mark.blender]

REPO = Path(__file__).resolve().parents[1]
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"
# every stage of the linear chain at once
EVERYTHING = {"profile": "indoor_dome", "metering": "region", "metering_region": [0.25, 0.25, 0.75, 0.75],
              "exposure_bias_ev": 0.3, "wdr_stops": 3.0, "psf_sigma_px": 0.8, "sharpen": 1.0,
              "compression": "h264_like", "quality": 60}


def document() -> dict:
    """The minimal example, frame 0: cam_01 plain; ``dome`` (a copy of cam_01) with every stage;
    ``fisheye`` (cam_02) with the fisheye_ceiling profile."""
    doc = json.loads(MINIMAL.read_text())
    body = doc["openlabel"]
    body["metadata"]["usdscene"]["frame_range"] = {"frame_start": 0, "frame_end": 0}
    body["metadata"]["usdscene"].pop("exports", None)
    body["metadata"]["usdscene"]["asset_paths"] = [str((MINIMAL.parent / p).resolve()) for p in body["metadata"]["usdscene"]["asset_paths"]]
    dome = copy.deepcopy(body["streams"]["cam_01"])
    dome["stream_properties"]["usdscene"]["sensor"] = EVERYTHING
    body["streams"]["dome"] = dome
    body["streams"]["cam_02"]["stream_properties"]["usdscene"]["sensor"] = {"profile": "fisheye_ceiling"}
    return doc


def run(tmp_path: Path, name: str) -> Path:
    from usdscene.pipeline import RunOptions, run_pipeline

    path = tmp_path / f"{name}.openlabel.json"
    path.write_text(json.dumps(document()))
    out = tmp_path / name
    run_pipeline(path, out, RunOptions(exports=[], report=False, keep_clean=True), progress=False)
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("camera")
    return run(folder, "a"), run(folder, "b")


def read(path: Path) -> np.ndarray:
    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


def test_masks_are_byte_identical_with_every_stage_on(runs):
    out, _ = runs
    plain = layout.mask_path(out, "cam_01", 0).read_bytes()
    assert layout.mask_path(out, "dome", 0).read_bytes() == plain
    assert np.count_nonzero(read(layout.mask_path(out, "dome", 0))) > 0
    image, clean = read(layout.image_path(out, "dome", 0)), read(layout.clean_image_path(out, "dome", 0))
    assert image.shape == clean.shape and np.abs(image.astype(int) - clean).mean() > 2
    # --keep-clean: the render before the camera is what the plain camera wrote
    assert layout.clean_image_path(out, "dome", 0).read_bytes() == layout.image_path(out, "cam_01", 0).read_bytes()


def test_same_document_same_bytes(runs):
    a, b = runs
    for camera in ("dome", "cam_02"):
        assert layout.image_path(a, camera, 0).read_bytes() == layout.image_path(b, camera, 0).read_bytes()


def test_the_chosen_exposure_is_in_the_annotations(runs):
    out, _ = runs
    document = json.loads((out / "annotations.openlabel.json").read_text())
    streams = document["openlabel"]["frames"]["0"]["frame_properties"]["usdscene"]["streams"]
    for camera in ("dome", "cam_02"):
        record = streams[camera]["sensor"]["exposure"]
        on_disk = json.loads(layout.exposure_path(out, camera, 0).read_text())
        assert record == on_disk and set(record) == {"exposure_ev", "metered_luminance"}
        assert record["metered_luminance"] > 0
    assert streams["dome"]["sensor"]["profile"] == "indoor_dome"
    assert "exposure" not in streams.get("cam_01", {}).get("sensor", {})
    # the exposure brings the metered grey to the target (plus the bias), within the limits
    record = streams["dome"]["sensor"]["exposure"]
    expected = float(np.clip(np.log2(0.2 / record["metered_luminance"]), -10.0, 10.0)) + 0.3
    assert record["exposure_ev"] == pytest.approx(expected, abs=2e-4)
