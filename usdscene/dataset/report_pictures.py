"""The pictures of the browsable report (:mod:`usdscene.dataset.report`): each image's
thumbnail (``report/thumbs/``, JPEG, ``THUMB_WIDTH_PX`` wide, for images wider than
``THUMB_ABOVE_PX``) and mask tint (``report/tints/``, 8-bit colour indices of the instance
mask, :func:`tint_indices`), drawn by a thread pool when the report is built
(:class:`PictureDrawing`) or while the images render (:class:`PicturesWhileRendering`).
A picture is redrawn only when its image or mask is newer.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

from usdscene.document import output_layout as layout

log = logging.getLogger(__name__)

REPORT_DIR = "report"
THUMBS_DIR = "thumbs"
TINTS_DIR = "tints"
THUMB_WIDTH_PX = 160
# Smaller images are their own thumbnails: the browser decodes only those in view (lazy
# loading), and a thumbnail would cost a full decode per image at build time.
THUMB_ABOVE_PX = 2 * THUMB_WIDTH_PX


def picture_paths(target: Path, camera: str, frame: int) -> tuple[Path, Path]:
    """``(thumbnail, tint)`` of one image inside a report folder."""
    return (target / THUMBS_DIR / camera / f"{frame:06d}.jpg",
            target / TINTS_DIR / camera / layout.frame_file(frame))


def fill_sizes(out: Path, images: list[dict]) -> None:
    """Fill in the size of images whose labels did not give it (a half-finished run), from
    their PNG headers; the label pages need it before the pictures are drawn."""
    for image in images:
        if image["width"] is None:
            size = _png_size(out / image["uri"])
            if size is not None:
                image["width"], image["height"] = size


class PictureDrawing:
    """Thumbnails and tints that are missing or older than their sources, drawn by a thread
    pool from construction on; :meth:`results` waits for them."""

    def __init__(self, out: Path, target: Path, images: list[dict], workers: int | None) -> None:
        from concurrent.futures import ThreadPoolExecutor

        # OpenCV releases the interpreter lock while it decodes, resizes and encodes; numpy's
        # take, zlib and file writes do too.
        count = max(1, workers or os.cpu_count() or 1)
        self._pool = ThreadPoolExecutor(max_workers=count)
        self._futures = [self._pool.submit(_draw_chunk, out, target, images[k:k + 64])
                         for k in range(0, len(images), 64)]

    def results(self) -> tuple[int, list[int]]:
        """``(pictures drawn, per image: 0 no image file, 1 thumbnail, 2 the image is its own
        thumbnail)``, once every picture is drawn.

        Raises:
            OutputError: a picture cannot be written.
        """
        results = [r for future in self._futures for r in future.result()]
        return sum(r[0] for r in results), [r[1] for r in results]

    def close(self) -> None:
        """Stop drawing (after an error elsewhere: the pictures not started are dropped)."""
        for future in self._futures:
            future.cancel()
        self._pool.shutdown(wait=True)


def _draw_chunk(out: Path, target: Path, images: list[dict]) -> list[tuple[int, int, tuple[int, int] | None]]:
    return [_draw_one(out, target, image) for image in images]


class PicturesWhileRendering:
    """A render event handler (``render(..., on_event=...)``) that draws each image's thumbnail
    and mask tint into ``report_dir`` as soon as the renderer reports it written, so that the
    report at the end of a run only writes its data (the pixels were read while the next images
    rendered). A failure is logged and drawing stops; :func:`build_report` draws what is missing.

    Attributes:
        pictures: thumbnails and tints drawn.
        seconds: wall seconds spent drawing.
    """

    def __init__(self, out_dir: str | os.PathLike, report_dir: str | os.PathLike | None = None) -> None:
        self.out = Path(out_dir)
        self.target = Path(report_dir) if report_dir is not None else self.out / REPORT_DIR
        self.pictures = 0
        self.seconds = 0.0
        self._failed = False

    def __call__(self, event: dict) -> None:
        from usdscene.errors import UsdSceneError

        if event.get("event") != "done" or self._failed:
            return
        started = time.perf_counter()
        camera, frame = str(event["camera"]), int(event["frame"])
        image = {"camera": camera, "frame": frame, "width": None, "height": None,
                 "uri": f"{layout.IMAGES_DIR}/{camera}/{layout.frame_file(frame)}",
                 "mask_uri": f"{layout.MASKS_DIR}/{camera}/{layout.frame_file(frame)}"}
        try:
            self.pictures += _draw_one(self.out, self.target, image)[0]
        except (UsdSceneError, OSError, ValueError) as exc:
            self._failed = True
            log.warning("drawing report pictures while rendering stopped (%s); the report draws them", exc)
        finally:
            self.seconds += time.perf_counter() - started


def _newer(source: Path, picture: Path) -> bool:
    """True when ``picture`` must be drawn again: missing, empty or older than ``source``."""
    try:
        kept = picture.stat()
    except OSError:
        return True
    return kept.st_size == 0 or kept.st_mtime_ns < source.stat().st_mtime_ns


def _draw_one(out: Path, target: Path, image: dict) -> tuple[int, int, tuple[int, int] | None]:
    """``(pictures drawn, thumbnail kind, (width, height) when the labels did not give it)`` of one image."""
    import cv2

    source = out / image["uri"]
    size = None if image["width"] is not None else _png_size(source)
    width = image["width"] if size is None else size[0]
    if width is None:
        return 0, 0, None
    thumb, tint = picture_paths(target, image["camera"], image["frame"])
    drawn = 0
    wants_thumb = width > THUMB_ABOVE_PX
    if wants_thumb and _newer(source, thumb):
        pixels = cv2.imread(str(source), cv2.IMREAD_COLOR)
        if pixels is None:
            return 0, 0, size
        height = max(1, round(pixels.shape[0] * THUMB_WIDTH_PX / pixels.shape[1]))
        small = cv2.resize(pixels, (THUMB_WIDTH_PX, height), interpolation=cv2.INTER_AREA)
        _write_picture(thumb, ".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, 85])
        drawn += 1
    # An image labelled with nothing in it has an all-background mask: no tint to show.
    empty = image.get("labelled", False) and not image.get("objects")
    mask = out / image["mask_uri"] if image["mask_uri"] and not empty else None
    if mask is not None and mask.is_file() and _newer(mask, tint):
        ids = cv2.imread(str(mask), cv2.IMREAD_UNCHANGED)
        if ids is not None and ids.ndim == 2:
            _write_bytes(tint, grey_png(tint_indices(ids)))
            drawn += 1
    return drawn, 1 if wants_thumb else 2, size


def _png_size(path: Path) -> tuple[int, int] | None:
    """``(width, height)`` from a PNG's header (its IHDR chunk), None when it is not a PNG."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(24)
    except OSError:
        return None
    if len(head) < 24 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def tint_indices(ids):
    """(H, W) uint8 colour indices of an (H, W) uint16 instance-id mask: 0 background, else
    ``(id - 1) % 255 + 1``. The page colours index k with the k-th hue of its palette (an SVG
    colour table), so neighbouring ids differ and the file is a small grey PNG."""
    global _TINT_TABLE
    import numpy as np

    if _TINT_TABLE is None:
        table = (np.arange(65536) - 1) % 255 + 1
        table[0] = 0
        _TINT_TABLE = table.astype(np.uint8)
    # take: a third faster than fancy indexing, and it releases the interpreter lock
    return np.take(_TINT_TABLE, ids)


_TINT_TABLE = None


def grey_png(pixels) -> bytes:
    """An 8-bit greyscale PNG of (H, W) uint8 ``pixels``: every row unfiltered, one zlib
    stream at level 1.

    A tint is mostly runs of one index, which zlib packs without the row filters; OpenCV's
    encoder tries every filter on every row and took 0.6 ms for a 320x240 tint, this takes
    0.1 ms. The bytes depend only on the pixels and zlib's level-1 output.
    """
    import struct
    import zlib

    import numpy as np

    height, width = pixels.shape
    rows = np.zeros((height, width + 1), np.uint8)  # filter byte 0 (none) before each row
    rows[:, 1:] = pixels

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows.tobytes(), 1)) + chunk(b"IEND", b""))


def _write_picture(path: Path, ext: str, pixels, params: list[int]) -> None:
    """Encode and replace ``path`` (temporary file + rename, no fsync: a lost picture is redrawn)."""
    import cv2

    from usdscene.errors import OutputError

    ok, encoded = cv2.imencode(ext, pixels, params)
    if not ok:
        raise OutputError(f"cannot encode a {pixels.shape} picture", where=str(path))
    _write_bytes(path, encoded.tobytes())


def _write_bytes(path: Path, data: bytes) -> None:
    """Replace ``path`` with ``data`` (temporary file + rename, no fsync: a lost picture is redrawn)."""
    from usdscene.errors import OutputError

    tmp = path.with_name(f".{path.name}.{os.getpid()}.{id(data)}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise OutputError(f"cannot write: {exc.strerror or exc}", where=str(path)) from None
