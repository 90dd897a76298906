"""Video export of an annotated moving sequence: one H.264 MP4 per camera. No pxr, no bpy.

``OUT/exports/video/<camera>.mp4``: the camera's rendered images (the document's image uris,
``images/<camera>/<frame:06d>.png``) in frame order, one video frame per labelled frame, at the
document's frame rate (``metadata.usdscene.fps``; a non-integer rate is kept as a fraction).
Video frame ``k`` (0-based, presentation time ``k / fps``) is the ``k``-th labelled frame of that
camera: with the MOT export's numbering (:mod:`usdscene.converters.exports.mot`), MOT frame
``k + 1`` when the frames have no gaps. ``OUT/exports/video/videos.json`` lists per camera the
document frame of each video frame, the rate, the codec and the quality.

Encoded by FFmpeg's libx264 through PyAV (the ``video`` extra; imported only here): H.264 High
profile, ``yuv420p`` (what every player decodes; chroma at half resolution, so odd image sizes
are padded by one black row/column on the right/bottom, recorded in ``videos.json``), constant
quality ``crf`` (default :data:`DEFAULT_CRF`; 0 is lossless in luma and chroma), ``veryslow``
preset off the table for speed: :data:`PRESET`. One encoder thread per video, so the bytes are
the same on every machine for the same images and settings (x264 with several threads is
deterministic too, but the stream then depends on the thread count).
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

from usdscene.converters.exports.tracks import require_tracks
from usdscene.converters.openlabel.annotations import image_records
from usdscene.errors import OutputError
from usdscene.files import dumps_json, staged_folder

VIDEO_DIR = "video"
VIDEO_INDEX = "videos.json"
DEFAULT_CRF = 18
PRESET = "medium"
CODEC = "libx264"


def frame_rate(fps: float) -> Fraction:
    """The frame rate as a fraction (29.97 → 30000/1001 style rates kept exactly to 1e-6)."""
    return Fraction(fps).limit_denominator(1001)


def export_video(document: dict, out_dir: str | os.PathLike, *, crf: int = DEFAULT_CRF) -> Path:
    """Write ``OUT/exports/video/`` (see the module docstring) in one staged folder.

    Args:
        document: the annotated document (``OUT/annotations.openlabel.json``).
        out_dir: the output folder holding it and its images.
        crf: x264 constant rate factor, 0 (lossless) .. 51.

    Returns:
        The folder written.

    Raises:
        OutputError: the document states no frame rate (a still document), ``crf`` is out of
            range, an image is missing or unreadable, or PyAV is not installed.
    """
    import json  # noqa: F401  (the index is written with dumps_json)

    fps = require_tracks(document, "video")
    if not isinstance(crf, int) or isinstance(crf, bool) or not 0 <= crf <= 51:
        raise OutputError(f"crf {crf!r} is not an integer from 0 to 51", where="video.crf")
    try:
        import av
    except ImportError:
        raise OutputError("the video export needs PyAV: pip install 'usdscene[video]'", where="video") from None
    out = Path(out_dir)
    by_camera: dict[str, list[dict]] = {}
    for record in image_records(document):
        by_camera.setdefault(record["camera"], []).append(record)
    if not by_camera:
        raise OutputError("the document has no labelled images to make videos of", where=str(out))
    rate = frame_rate(fps)
    index = {"fps": fps, "codec": "h264", "encoder": CODEC, "crf": crf, "preset": PRESET,
             "pixel_format": "yuv420p", "cameras": {}}
    with staged_folder(out / "exports" / VIDEO_DIR, what="video export") as folder:
        for camera in sorted(by_camera):
            records = sorted(by_camera[camera], key=lambda r: r["frame"])
            path = folder / f"{camera}.mp4"
            width, height = encode_video(av, path, [out / r["uri"] for r in records], rate, crf)
            index["cameras"][camera] = {"file": path.name, "frames": [int(r["frame"]) for r in records],
                                        "width_px": width, "height_px": height,
                                        "image_width_px": int(records[0]["width_px"]),
                                        "image_height_px": int(records[0]["height_px"])}
        (folder / VIDEO_INDEX).write_text(dumps_json(index) + "\n", encoding="utf-8")
    return out / "exports" / VIDEO_DIR


def encode_video(av, path: Path, images: list[Path], rate: Fraction, crf: int) -> tuple[int, int]:
    """Encode PNG images into one MP4 → the video's (width, height) in pixels."""
    import cv2
    import numpy as np

    container = av.open(str(path), mode="w", format="mp4")
    try:
        stream = None
        for k, image_path in enumerate(images):
            image = cv2.imread(str(image_path), cv2.IMREAD_COLOR)
            if image is None:
                raise OutputError("missing or unreadable image", where=str(image_path))
            if stream is None:
                height, width = image.shape[:2]
                # yuv420p needs even sizes: pad by one black row/column rather than scale.
                size = (width + width % 2, height + height % 2)
                stream = container.add_stream(CODEC, rate=rate)
                stream.width, stream.height = size
                stream.pix_fmt = "yuv420p"
                stream.thread_count = 1
                stream.options = {"crf": str(crf), "preset": PRESET}
            if image.shape[1] != width or image.shape[0] != height:
                raise OutputError(f"image of {image.shape[1]}x{image.shape[0]} px in a video of "
                                  f"{width}x{height} px", where=str(image_path))
            if size != (width, height):
                padded = np.zeros((size[1], size[0], 3), np.uint8)
                padded[:height, :width] = image
                image = padded
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="bgr24")
            frame.pts = k
            for packet in stream.encode(frame):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    finally:
        container.close()
    return size


def write_video(job) -> Path:
    """The registry's writer (:mod:`usdscene.converters.exports.registry`): :func:`export_video`
    of an :class:`~usdscene.converters.exports.registry.ExportJob`."""
    return export_video(job.document, job.out_dir)
