"""ROI crops for place classification (is a bag stowed correctly?), from an annotated document.

For every image of the document (frame × camera) and every region of every place the document
names (``seat_03A`` → its ``is_on``, ``is_below``, ``is_in_front_of`` ... regions in the asset
catalog), the region's box (catalog pose and size, see :class:`usdscene.scene.catalog.PlaceRegion`)
is projected through the camera (:func:`usdscene.labels.projection.project_points`, every lens model)
and cropped from the image when the camera sees it:

* all 8 corners are valid for the lens (in front of the camera, inside its field of view);
* at least ``min_inside_fraction`` of the projected box lies inside the image;
* the clipped crop is at least ``min_size_px`` wide and high.

Label of a crop: the document's ``roi_rules`` (``metadata.usdscene.roi_rules``) applied to the
relation of the region when some present object is in it at that frame, directly or through a
chain of relations (``bag is_on suitcase is_below seat_03A`` is in seat_03A's ``is_below``
region, see :func:`usdscene.converters.openlabel.annotations.resolve_places`) (rule keys
``"<place kind>:<relation>"`` win over ``"<relation>"``; without a rule the relation name
itself), and ``empty`` when no object is there. Example rules for taxi, take-off and landing:
``{"is_below": "correct", "is_on": "incorrect", "is_in_front_of": "incorrect"}``.

Objects of the classes or catalog kinds in ``metadata.usdscene.roi_ignore`` (the cabin:
``["passenger"]``) are not judged: they do not make a region occupied, so a seat holding only
a seated passenger is ``empty``; a bag on that passenger's lap still makes the seat's ``is_on``
region ``incorrect`` (it rests on the seat through the passenger).

Output (an image-folder dataset)::

    exports/rois/<label>/<camera>_<frame:06d>_<place>_<relation>.png
    exports/rois/index.csv   path,label,camera,frame,place,place_kind,relation,objects,x,y,w,h,image,ignored

``x, y, w, h`` is the crop in the source image (pixels, top-left corner, pixel ``i`` covers
``[i, i + 1)``), ``objects`` the uids in the region that the label judges, ``ignored`` those of
``roi_ignore`` classes in it, each separated by ``;``.
"""

from __future__ import annotations

import csv
import io
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdscene.converters.openlabel.annotations import image_records, resolve_places_over
from usdscene.document import output_layout as layout
from usdscene.scene.catalog import Catalog, PlaceRegion
from usdscene.errors import AssetError, DocumentError, OutputError
from usdscene.files import write_png_atomic, write_text_atomic
from usdscene.document.model import Camera

log = logging.getLogger(__name__)

ROIS_DIR = "rois"
INDEX_FILE = "index.csv"
EMPTY_LABEL = "empty"
CSV_COLUMNS = ("path", "label", "camera", "frame", "place", "place_kind", "relation", "objects",
               "x", "y", "w", "h", "image", "ignored")


@dataclass(frozen=True)
class RoiCrop:
    """One crop.

    Attributes:
        camera, frame: the source image.
        place: place name; place_kind: its kind (seat, bin, aisle).
        relation: the region's relation (``is_below`` ...).
        label: class label (rule result or ``empty``).
        objects: uids of the objects in the region that the label judges.
        ignored: uids of the objects in the region whose class or kind the document's
            ``roi_ignore`` names (they leave the label ``empty``).
        x_min, y_min, x_max, y_max: inclusive pixel bounds of the crop in the image.
    """

    camera: str
    frame: int
    place: str
    place_kind: str
    relation: str
    label: str
    objects: tuple[str, ...]
    x_min: int
    y_min: int
    x_max: int
    y_max: int
    ignored: tuple[str, ...] = ()


def region_corners(region: PlaceRegion) -> np.ndarray:
    """(8, 3) world corners of a region box (its frame: z = 0 support plane, z up)."""
    sx, sy, sz = region.size_m
    local = np.array([[x, y, z] for x in (-sx / 2, sx / 2) for y in (-sy / 2, sy / 2) for z in (0.0, sz)])
    return region.pose.transform_points(local)


def region_crop_box(camera: Camera, region: PlaceRegion, frame: int, *, min_size_px: int = 8,
                    min_inside_fraction: float = 0.5) -> tuple[int, int, int, int] | None:
    """Inclusive pixel bounds ``(x_min, y_min, x_max, y_max)`` of the region's projected box
    clipped to the image, or None when the camera does not see it (see the module docstring)."""
    from usdscene.labels.projection import project_points

    uv, valid = project_points(camera, region_corners(region), frame)
    if not valid.all():
        return None
    width, height = camera.intrinsics.width_px, camera.intrinsics.height_px
    # Pixel-centre coordinates → pixel edges: pixel i spans [i - 0.5, i + 0.5].
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    full_area = max(hi[0] - lo[0], 1e-9) * max(hi[1] - lo[1], 1e-9)
    clo = np.maximum(lo, -0.5)
    chi = np.minimum(hi, [width - 0.5, height - 0.5])
    if (chi <= clo).any():
        return None
    if (chi[0] - clo[0]) * (chi[1] - clo[1]) < min_inside_fraction * full_area:
        return None
    # Pixels that the clipped box overlaps: the one holding each clipped edge.
    x0, y0 = (int(v) for v in np.floor(clo + 0.5))
    x1, y1 = (int(v) for v in np.ceil(chi + 0.5) - 1)
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, width - 1), min(y1, height - 1)
    if x1 - x0 + 1 < min_size_px or y1 - y0 + 1 < min_size_px:
        return None
    return (x0, y0, x1, y1)


def _occupants(resolved: dict[str, tuple[str, str]], place_uid: str, relation: str) -> tuple[str, ...]:
    return tuple(sorted(uid for uid, (place, rel) in resolved.items() if place == place_uid and rel == relation))


def _label(rules, kind: str, relation: str, occupied: bool) -> str:
    if not occupied:
        return EMPTY_LABEL
    return str(rules.get(f"{kind}:{relation}", rules.get(relation, relation)))


def plan_rois(document: dict, catalog: Catalog, *, min_size_px: int = 8,
              min_inside_fraction: float = 0.5) -> list[RoiCrop]:
    """Every crop of an annotated document, sorted by (frame, camera, place, relation).

    Raises:
        DocumentError: the document does not read as a scene.
        AssetError: its environment, one of its places or a ``roi_ignore`` class or kind is not
            in the catalog.
    """
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.converters.openlabel.read import roi_ignored_classes

    from usdscene.converters.openlabel.store import scene_document

    scene = read_openlabel(scene_document(document))
    if not scene.places:
        return []
    if scene.environment is None or scene.environment not in catalog:
        raise AssetError(f"environment {scene.environment!r} is not in the asset catalog",
                         where="openlabel.metadata.usdscene.environment")
    from usdscene.scene.catalog import scene_catalog

    env_places = scene_catalog(catalog, scene).places(scene.environment)  # declared places too
    missing = [p.name for p in scene.places if p.name not in env_places]
    if missing:
        raise AssetError(f"places {missing} are not in environment {scene.environment!r}",
                         where="openlabel.objects")
    ignored_classes, problems = roi_ignored_classes(scene.roi_ignore, catalog, "openlabel.metadata.usdscene.roi_ignore")
    if problems:
        raise AssetError(problems)
    ignored = {o.uid for o in scene.objects if o.class_name in ignored_classes}
    if not scene.roi_rules:
        log.warning("the document has no roi_rules; occupied regions are labelled by relation name")
    cameras = {c.name: c for c in scene.cameras}
    crops = []
    records = image_records(document)
    resolved = resolve_places_over(scene, {r["frame"] for r in records})
    for record in records:
        camera = cameras.get(record["camera"])
        if camera is None:
            raise DocumentError(f"image of unknown camera {record['camera']!r}",
                                where=f"openlabel.frames.{record['frame']}.frame_properties.streams")
        for place_ref in scene.places:
            place = env_places[place_ref.name]
            for relation, region in sorted(place.regions.items()):
                box = region_crop_box(camera, region, record["frame"], min_size_px=min_size_px,
                                      min_inside_fraction=min_inside_fraction)
                if box is None:
                    continue
                occupants = _occupants(resolved[record["frame"]], place_ref.uid, relation)
                judged = tuple(uid for uid in occupants if uid not in ignored)
                crops.append(RoiCrop(camera=camera.name, frame=record["frame"], place=place.name,
                                     place_kind=place.kind, relation=relation,
                                     label=_label(scene.roi_rules, place.kind, relation, bool(judged)),
                                     objects=judged, x_min=box[0], y_min=box[1], x_max=box[2], y_max=box[3],
                                     ignored=tuple(uid for uid in occupants if uid in ignored)))
    return sorted(crops, key=lambda c: (c.frame, c.camera, c.place, c.relation))


def export_rois(document: dict, out_dir: str | os.PathLike, catalog: Catalog, *, min_size_px: int = 8,
                min_inside_fraction: float = 0.5) -> Path:
    """Crop every visible place region of every image; write the dataset and its CSV index.

    Args:
        document: annotated OpenLABEL document (image uris relative to ``out_dir``).
        out_dir: the output folder holding the document and ``images/``.
        catalog: asset catalog with the environment's places.
        min_size_px: smallest crop side kept, pixels.
        min_inside_fraction: smallest part of the projected box that must lie in the image.

    Returns:
        The ``exports/rois`` folder.

    Raises:
        OutputError: an image the document names cannot be read.
    """
    import cv2

    out = Path(out_dir)
    root = out / layout.EXPORTS_DIR / ROIS_DIR
    uris = {(r["frame"], r["camera"]): r["uri"] for r in image_records(document)}
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    loaded: dict[str, np.ndarray] = {}
    for crop in plan_rois(document, catalog, min_size_px=min_size_px, min_inside_fraction=min_inside_fraction):
        uri = uris[(crop.frame, crop.camera)]
        if uri not in loaded:
            loaded.clear()  # one image at a time: crops are sorted by image
            image = cv2.imread(str(out / uri), cv2.IMREAD_UNCHANGED)
            if image is None:
                raise OutputError(f"cannot read image {uri!r}", where=str(out / uri))
            loaded[uri] = image
        pixels = loaded[uri][crop.y_min:crop.y_max + 1, crop.x_min:crop.x_max + 1]
        name = f"{crop.camera}_{layout.frame_file(crop.frame)[:-4]}_{crop.place}_{crop.relation}.png"
        relative = Path(crop.label) / name
        write_png_atomic(root / relative, pixels)
        writer.writerow([relative.as_posix(), crop.label, crop.camera, crop.frame, crop.place,
                         crop.place_kind, crop.relation, ";".join(crop.objects), crop.x_min, crop.y_min,
                         crop.x_max - crop.x_min + 1, crop.y_max - crop.y_min + 1, uri, ";".join(crop.ignored)])
    write_text_atomic(root / INDEX_FILE, buffer.getvalue())
    return root


def write_rois(job) -> Path:
    """The registry's writer (:mod:`usdscene.converters.exports.registry`): :func:`export_rois`
    of an :class:`~usdscene.converters.exports.registry.ExportJob`."""
    return export_rois(job.document, job.out_dir, job.catalog, min_size_px=job.options.min_roi_px)
