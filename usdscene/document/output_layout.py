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
    """uid → mask id for every dynamic object: the one home of the id assignment.

    While the document's objects fit the uint16 mask (at most 65,535), ids are 1, 2, ... in
    document order: one id per object for the whole document. A longer document (thousands of
    people arriving and leaving over hours) gets ids per frame instead: an object keeps its id
    through its presence (``frame_intervals`` within the document's range, clipped; none = every
    frame), and objects that are never present on a common frame may share one (lowest free id
    first, objects taken by first frame, then document order). The limit then applies to the
    objects present at any one frame. ``masks/ids.json`` says which object owns a shared id on
    which frames (:func:`id_map_json`, :func:`mask_owners`).

    The environment (seats, walls) and places are background (0): labels are for the objects
    a detector must find. Ids are stable for a given document, whatever the executor. To give
    another kind of element its own ids (clutter, say), add it to the objects (or pass its
    presence here): do not number it anywhere else.

    Raises:
        ValueError: more objects present at one frame than a uint16 mask can hold (65535),
            naming the first such frame.
    """
    if len(scene.objects) <= MAX_MASK_ID:
        return {obj.uid: index + 1 for index, obj in enumerate(scene.objects)}
    import heapq

    spans = [(presence_span(obj.frame_intervals, scene.frame_start, scene.frame_end), index, obj.uid)
             for index, obj in enumerate(scene.objects)]
    # An object present on no frame of the range shows in no mask; the stage still needs an id
    # for it, and id 1 is never wrong there.
    ids: dict[str, int] = {uid: 1 for span, _, uid in spans if span is None}
    busy: list[tuple[int, int]] = []  # (last frame, id) of the objects still present
    free: list[int] = []
    next_id = 1
    for (first, last), _, uid in sorted((s for s in spans if s[0] is not None), key=lambda s: (s[0][0], s[1])):
        while busy and busy[0][0] < first:
            heapq.heappush(free, heapq.heappop(busy)[1])
        if free:
            mask_id = heapq.heappop(free)
        else:
            mask_id, next_id = next_id, next_id + 1
        if mask_id > MAX_MASK_ID:
            raise ValueError(f"{len(busy) + 1} objects present at frame {first} exceed the {MAX_MASK_ID} "
                             f"ids of a uint16 mask (ids are per frame in a document of "
                             f"{len(scene.objects)} objects)")
        ids[uid] = mask_id
        heapq.heappush(busy, (last, mask_id))
    return ids


def presence_span(intervals, frame_start: int, frame_end: int) -> tuple[int, int] | None:
    """``(first, last)`` frame of an object's presence within ``[frame_start, frame_end]``
    (no intervals = the whole range); None when it is present on no frame of the range. The
    span covers any gaps between intervals: an object keeps its id across them."""
    if not intervals:
        return (frame_start, frame_end)
    first = max(frame_start, min(iv.frame_start for iv in intervals))
    last = min(frame_end, max(iv.frame_end for iv in intervals))
    return (first, last) if first <= last else None


def id_map_json(objects) -> dict:
    """The ``masks/ids.json`` mapping of ``objects`` (each with ``uid``, ``class_name``,
    ``prim_path``, ``mask_id``, ``visible_frames``, as the stage reader gives them).

    ``{"<mask id>": {"uid", "class", "prim"}}`` for an id one object owns; for an id several
    objects share (per-frame ids, :func:`mask_ids`) the value is a list of those entries, each
    with ``"frames": [[first, last], ...]``, the closed frame ranges where it owns the id.
    """
    by_id: dict[int, list] = {}
    for o in objects:
        by_id.setdefault(int(o.mask_id), []).append(o)
    out: dict = {}
    for mask_id, owners in by_id.items():
        if len(owners) == 1:
            o = owners[0]
            out[str(mask_id)] = {"uid": o.uid, "class": o.class_name, "prim": o.prim_path}
        else:
            out[str(mask_id)] = [{"uid": o.uid, "class": o.class_name, "prim": o.prim_path,
                                  "frames": _frame_ranges(o.visible_frames)} for o in owners]
    return out


def _frame_ranges(frames) -> list[list[int]]:
    ranges: list[list[int]] = []
    for f in frames:
        if ranges and ranges[-1][1] == f - 1:
            ranges[-1][1] = f
        else:
            ranges.append([int(f), int(f)])
    return ranges


def mask_owners(id_map: dict, frame: int | None = None) -> dict[int, str]:
    """mask id → uid at ``frame`` from a ``masks/ids.json`` mapping (:func:`id_map_json`); an
    id whose owners own no range holding ``frame`` is left out. ``frame=None``: the ids one
    object owns only.

    Raises:
        KeyError, TypeError, ValueError: a malformed mapping.
    """
    out: dict[int, str] = {}
    for key, value in id_map.items():
        if isinstance(value, list):
            if frame is None:
                continue
            for owner in value:
                if any(int(a) <= frame <= int(b) for a, b in owner["frames"]):
                    out[int(key)] = str(owner["uid"])
                    break
        else:
            out[int(key)] = str(value["uid"])
    return out


def id_map_entries(id_map: dict) -> list[dict]:
    """Every owner entry of a ``masks/ids.json`` mapping (``uid``, ``class``, ...), shared ids'
    owners each once."""
    return [owner for value in id_map.values() for owner in (value if isinstance(value, list) else [value])]
