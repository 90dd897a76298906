"""The output folder layout and the uid → mask id assignment. Pure module.

::

    out/stage/...                       composed USD stage (see usdscene.document.stage_schema)
    out/images/<camera>/<frame:06d>.png 8-bit RGB
    out/masks/<camera>/<frame:06d>.png  16-bit instance ids, 0 = background
    out/masks/ids.json                  {"<mask id>": {"uid", "class", "name"}}
    out/depth/<camera>/<frame:06d>.png|.exr  distance to the image plane (render.depth: 16-bit
                                        millimetres or float metres; usdscene.render.depth)
    out/labels/<camera>/<frame:06d>.json labels of one image, kept so they are computed once
    out/annotations/index.json          the annotation store: index of the shards below
    out/annotations/static.openlabel.json  the document without its frames
    out/annotations/frames/<first:06d>-<last:06d>.json  OpenLABEL frames of a frame range
    out/annotations.openlabel.json      input + per-frame, per-camera labels and image uris, in one
                                        document (written from the store for small runs)
    out/exports/<format>/...            coco, yolo, rois
    out/manifest.json                   finished (frame, camera) pairs, versions, timings

Every writer and reader takes these paths from here.
"""

from __future__ import annotations

from pathlib import Path

from usdscene.document.model import SceneSpec

STAGE_DIR = "stage"
IMAGES_DIR = "images"
MASKS_DIR = "masks"
CLEAN_IMAGES_DIR = "images_clean"  # images before sensor effects (--keep-clean)
EXPOSURE_DIR = "exposure"  # per image: what the camera's auto exposure chose (linear chain only)
EXPORTS_DIR = "exports"
LABELS_DIR = "labels"
DEPTH_DIR = "depth"
ID_MAP_FILE = "masks/ids.json"
MANIFEST_FILE = "manifest.json"
ANNOTATIONS_FILE = "annotations.openlabel.json"
ANNOTATION_STORE_DIR = "annotations"  # usdscene.converters.openlabel.store

BACKGROUND_ID = 0
MAX_MASK_ID = 65535  # masks are uint16


def frame_file(frame: int) -> str:
    """File name of a frame's image or mask: ``000012.png``."""
    return f"{frame:06d}.png"


def image_path(out_dir: str | Path, camera: str, frame: int) -> Path:
    """``out/images/<camera>/<frame:06d>.png``."""
    return Path(out_dir) / IMAGES_DIR / camera / frame_file(frame)


def mask_path(out_dir: str | Path, camera: str, frame: int) -> Path:
    """``out/masks/<camera>/<frame:06d>.png`` (16-bit instance ids)."""
    return Path(out_dir) / MASKS_DIR / camera / frame_file(frame)


def depth_path(out_dir: str | Path, camera: str, frame: int, depth_format: str) -> Path:
    """``out/depth/<camera>/<frame:06d>.exr`` for ``exr``, ``.png`` for ``png16``."""
    suffix = ".exr" if depth_format == "exr" else ".png"
    return Path(out_dir) / DEPTH_DIR / camera / f"{frame:06d}{suffix}"


def clean_image_path(out_dir: str | Path, camera: str, frame: int) -> Path:
    """The image before the camera's sensor effects (``--keep-clean``)."""
    return Path(out_dir) / CLEAN_IMAGES_DIR / camera / frame_file(frame)


def exposure_path(out_dir: str | Path, camera: str, frame: int) -> Path:
    """``out/exposure/<camera>/<frame:06d>.json``: the exposure the camera applied to one image
    (:func:`usdscene.sensor.pipeline.process_image`), read into the annotations."""
    return Path(out_dir) / EXPOSURE_DIR / camera / f"{frame:06d}.json"


def labels_path(out_dir: str | Path, camera: str, frame: int) -> Path:
    """Labels of one image (see :class:`usdscene.dataset.annotation.ImageLabeller`)."""
    return Path(out_dir) / LABELS_DIR / camera / f"{frame:06d}.json"


def stage_root(out_dir: str | Path) -> Path:
    """Root layer of the composed stage: ``out/stage/scene.usda``."""
    return Path(out_dir) / STAGE_DIR / "scene.usda"


def mask_ids(scene: SceneSpec) -> dict[str, int]:
    """uid → mask id for every dynamic object: 1, 2, ... in document order.

    The environment (seats, walls) and places are background (0): labels are for the objects
    a detector must find. Ids are stable for a given document, whatever the executor.

    Raises:
        ValueError: more objects than a uint16 mask can hold (65535).
    """
    if len(scene.objects) > MAX_MASK_ID:
        raise ValueError(f"{len(scene.objects)} objects exceed the {MAX_MASK_ID} ids of a uint16 mask")
    return {obj.uid: index + 1 for index, obj in enumerate(scene.objects)}
