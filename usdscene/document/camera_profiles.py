"""Named camera profiles: the sensor, optics and processing of a kind of surveillance camera as
defaults of :class:`usdscene.document.imaging.Sensor` (``"sensor": {"profile": "indoor_dome"}``;
fields given beside the profile win; :func:`usdscene.document.imaging.profile_sensor`). Pure
module (stdlib), data only.

The values are typical of current 2-4 MP (fisheye: 12 MP) CCTV cameras, not the data sheet of
one model:

* full well and read noise: small-pixel CMOS sensors (1.5-3 µm pixels hold roughly 4,000-10,000
  electrons; read noise 1.5-3 e⁻);
* gain (``iso``): chosen so that mid grey carries about 1.5-2.5 grey levels of noise after the
  processing (measured on the shipped examples with ``benchmarks/look_statistics.py``, as real
  footage measures 1.6: docs/sensors.md);
* lens: MTF50 of 0.2-0.3 cycles per pixel (an inexpensive M12 lens wide open; a fisheye is softer
  towards its edge, taken here as one value); vignetting of such lenses at full aperture;
* processing: auto exposure, digital WDR of 1.5-3 stops, moderate sharpening with halos, 4:2:0
  chroma and JPEG snapshots at quality 85-92 (the stills a camera serves; a video stream's
  blockiness is ``compression: h264_like``).
"""

from __future__ import annotations

from typing import Any, Mapping

# name → field values (the sensor block's document form) and a one-line description.
PROFILES: dict[str, dict[str, Any]] = {
    "indoor_dome": {
        "iso": 400, "full_well_e": 8000.0, "read_noise_e": 2.5, "vignetting": 0.25,
        "auto_exposure": True, "metering": "centre_weighted", "target_grey": 0.2,
        "exposure_speed": 1.0, "wdr_stops": 2.5,
        "mtf50_cy_px": 0.28, "sharpen": 0.6, "sharpen_radius_px": 1.0, "chroma_420": True,
        "compression": "jpeg", "quality": 90,
    },
    "outdoor_bullet": {
        "iso": 400, "full_well_e": 9000.0, "read_noise_e": 2.0, "vignetting": 0.3,
        "auto_exposure": True, "metering": "average", "target_grey": 0.18,
        "exposure_speed": 1.0, "wdr_stops": 1.5,
        "mtf50_cy_px": 0.3, "sharpen": 0.8, "sharpen_radius_px": 1.0, "chroma_420": True,
        "compression": "jpeg", "quality": 90,
    },
    "fisheye_ceiling": {
        "iso": 320, "full_well_e": 4500.0, "read_noise_e": 2.2, "vignetting": 0.45,
        "auto_exposure": True, "metering": "centre_weighted", "target_grey": 0.2,
        "exposure_speed": 1.0, "wdr_stops": 3.0,
        "mtf50_cy_px": 0.28, "sharpen": 1.0, "sharpen_radius_px": 1.2, "chroma_420": True,
        "compression": "jpeg", "quality": 88,
    },
    "ir_night": {
        "ir_night": True, "ir_range_m": 20.0,
        "iso": 1600, "full_well_e": 8000.0, "read_noise_e": 3.0, "vignetting": 0.35,
        "auto_exposure": True, "metering": "centre_weighted", "target_grey": 0.16,
        "exposure_speed": 1.0, "wdr_stops": 1.0,
        "mtf50_cy_px": 0.2, "sharpen": 0.5, "sharpen_radius_px": 1.2,
        "compression": "jpeg", "quality": 85,
    },
}

DESCRIPTIONS = {
    "indoor_dome": "2 MP ceiling dome indoors: centre-weighted auto exposure, 2.5 stops of WDR",
    "outdoor_bullet": "4 MP bullet outdoors: average metering, 1.5 stops of WDR, a sharper lens",
    "fisheye_ceiling": "12 MP ceiling fisheye: small pixels, a soft lens, strong vignetting, 3 stops of WDR",
    "ir_night": "night mode: monochrome near infrared with the camera's illuminator, high gain",
}


def profile_fields(name: str) -> Mapping[str, Any]:
    """The field values of profile ``name`` (KeyError when unknown; the document reader refuses
    unknown names first)."""
    return PROFILES[name]
