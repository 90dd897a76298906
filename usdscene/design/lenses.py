"""The lens catalog of the camera planner: lens + sensor entries (shipped
``usdscene/data/lenses.json``, extended or overridden by a user file) and their intrinsics. Pure.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path


from usdscene.errors import DocumentError, ProblemCollector
from usdscene.document.model import Intrinsics, LensModel
from usdscene.lens import lens_for
from usdscene.shipped import shipped_data_file

from usdscene.labels.pixel_density import read_json_object

log = logging.getLogger(__name__)


LENSES_FILE = shipped_data_file("lenses.json")


@dataclass(frozen=True)
class Lens:
    """A lens + sensor entry of the lens catalog.

    Attributes:
        name: catalog key.
        model: projection model (``perspective``, ``fisheye_equisolid``, ...).
        focal_length_mm: focal length in millimetres.
        sensor_width_mm: sensor width in millimetres.
        fov_deg: fisheye image-circle field of view (degrees); None for pinhole lenses.
        resolution_px: (width, height) of the camera's image in pixels.
        description: free text.
    """

    name: str
    model: LensModel
    focal_length_mm: float
    sensor_width_mm: float
    resolution_px: tuple[int, int]
    fov_deg: float | None = None
    description: str = ""


def load_lenses(extra: str | os.PathLike | None = None) -> dict[str, Lens]:
    """The shipped lens catalog, extended (same name: replaced) by a user file.

    Args:
        extra: a JSON file of the same format as ``usdscene/data/lenses.json``.

    Returns:
        name → :class:`Lens`, in file order.

    Raises:
        DocumentError: a file is unreadable or an entry malformed (every problem at once).
    """
    problems = ProblemCollector()
    lenses = _read_lenses(LENSES_FILE, problems)
    if extra is not None:
        lenses.update(_read_lenses(Path(extra), problems))
    problems.raise_if_any(DocumentError)
    return lenses


def _read_lenses(path: Path, problems: ProblemCollector) -> dict[str, Lens]:
    data = read_json_object(path, problems)
    if data is None:
        return {}
    entries = data.get("lenses")
    if not isinstance(entries, dict) or not entries:
        problems.add(f"{path}:lenses", "expected a non-empty object of lens entries")
        return {}
    lenses = {}
    for name, raw in entries.items():
        where = f"{path}:lenses.{name}"
        if not isinstance(raw, dict):
            problems.add(where, f"expected an object, got {raw!r}")
            continue
        try:
            model = LensModel(raw.get("model"))
        except ValueError:
            problems.add(f"{where}.model", f"unknown lens model {raw.get('model')!r}; expected one of "
                                           f"{', '.join(m.value for m in LensModel)}")
            continue
        if not lens_for(model).catalog:
            problems.add(f"{where}.model", f"lens model {model.value!r} is not a catalog lens; use perspective, "
                                           "fisheye_equidistant or fisheye_equisolid")
            continue
        numbers = {}
        for key in ("focal_length_mm", "sensor_width_mm"):
            value = raw.get(key)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
                problems.add(f"{where}.{key}", f"expected a positive number, got {value!r}")
            else:
                numbers[key] = float(value)
        fov = raw.get("fov_deg")
        radial = lens_for(model).radial  # a fisheye: its image circle
        if radial and (not isinstance(fov, (int, float)) or not 0 < fov < 360):
            problems.add(f"{where}.fov_deg", f"a fisheye lens needs fov_deg in (0, 360), got {fov!r}")
            continue
        res = raw.get("resolution_px")
        if (not isinstance(res, list) or len(res) != 2
                or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in res)):
            problems.add(f"{where}.resolution_px", f"expected [width, height] in pixels, got {res!r}")
            continue
        if len(numbers) < 2:
            continue
        lenses[name] = Lens(name=name, model=model, focal_length_mm=numbers["focal_length_mm"],
                            sensor_width_mm=numbers["sensor_width_mm"], resolution_px=(res[0], res[1]),
                            fov_deg=float(fov) if radial else None,
                            description=str(raw.get("description", "")))
    return lenses


def lens_intrinsics(lens: Lens) -> Intrinsics:
    """Intrinsics of a catalog lens: square pixels, centred principal point.

    ``f_px = focal_length_mm · width_px / sensor_width_mm`` for every model (the same reading
    as the friendly camera form of the document for pinhole and equisolid lenses).
    """
    w, h = lens.resolution_px
    f = lens.focal_length_mm * w / lens.sensor_width_mm
    return Intrinsics(lens=lens.model, width_px=w, height_px=h, fx_px=f, fy_px=f,
                      cx_px=(w - 1) / 2.0, cy_px=(h - 1) / 2.0, fov_deg=lens.fov_deg,
                      sensor_width_mm=lens.sensor_width_mm)
