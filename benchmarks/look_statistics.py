"""Look statistics of images: how bright, clipped, crushed, noisy, sharp and colourful they are,
to compare renders with real camera footage.

    python benchmarks/look_statistics.py FOLDER [LABEL=FOLDER ...] [--markdown]

Each FOLDER is searched recursively for ``*.png`` / ``*.jpg`` / ``*.jpeg``; a run's output
folder (``OUT``) is read from ``OUT/images`` (masks and clean images are left out). The table
gives the mean over the images of each statistic:

* brightness: mean luma, 0-255 (Rec. 601 weights ``0.299 R + 0.587 G + 0.114 B`` of the
  8-bit values);
* clipped %: pixels with any channel >= 250;
* crushed %: pixels with luma <= 5;
* noise sigma: grey levels on flat areas. The residual of the luma after a 3x3 box filter, on
  the pixels whose local gradient (Sobel magnitude of the luma smoothed by a 9x9 Gaussian of
  sigma 2 px, so that the noise itself hardly moves it) lies in the image's lowest decile,
  neither clipped nor crushed; its standard deviation clipped at 3 sigma (five rounds, robust
  to the few edges left), divided by :data:`BOX_RESIDUAL_GAIN` so that i.i.d. Gaussian noise of
  sigma s reads s (within 3 % for s = 1-4 on 8-bit images; 8-bit rounding adds its own 0.29
  in quadrature, tests/test_look_statistics.py);
* sharpness: variance of the Laplacian (3x3 aperture) of the luma;
* colourfulness: Hasler and Süsstrunk (2003), ``sqrt(sd_rg² + sd_yb²) + 0.3 sqrt(mean_rg² +
  mean_yb²)`` with ``rg = R - G`` and ``yb = (R + G) / 2 - B``.

Brightness, clipped %, crushed % and noise are taken over the pixels the lens images: in a run's
output folder (``OUT``, its ``images`` / ``images_clean`` or a camera's folder in them) each camera's lens is read from
the run's stage, and a fisheye's images count only the pixels inside its image circle
(:func:`usdscene.lens.valid_pixels`; the renderer blacks out the rest, which would otherwise
read as crushed). Folders of other images count every pixel.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

# std(x - box3x3(x)) / sigma for i.i.d. Gaussian noise: the box mean shares the centre pixel,
# so the residual's variance is (8/9)² + 8/81 = 8/9 of the noise's; times 0.9866, the standard
# deviation of a unit Gaussian clipped at 3 sigma.
BOX_RESIDUAL_GAIN = float(np.sqrt(8.0 / 9.0) * 0.9866)
CLIP_SIGMAS = 3.0
FLAT_QUANTILE = 0.10
STATISTICS = ("brightness", "clipped_pct", "crushed_pct", "noise_sigma", "sharpness", "colourfulness")
HEADERS = {"brightness": "brightness", "clipped_pct": "clipped %", "crushed_pct": "crushed %",
           "noise_sigma": "noise σ", "sharpness": "sharpness", "colourfulness": "colourfulness"}
SUFFIXES = (".png", ".jpg", ".jpeg")


def luma_of(image_rgb_u8: np.ndarray) -> np.ndarray:
    """(H, W) float32 Rec. 601 luma, 0-255, of a (H, W, 3) uint8 RGB image."""
    rgb = image_rgb_u8.astype(np.float32)
    return rgb[..., 0] * np.float32(0.299) + rgb[..., 1] * np.float32(0.587) + rgb[..., 2] * np.float32(0.114)


def noise_sigma(luma: np.ndarray, usable: np.ndarray | None = None) -> float:
    """Noise in grey levels on the flattest decile of ``luma`` ((H, W) float32, 0-255).

    Args:
        luma: the image's luma.
        usable: (H, W) bool, pixels that may count (e.g. not clipped, not crushed); all if None.
    """
    residual = luma - cv2.blur(luma, (3, 3))
    smooth = cv2.GaussianBlur(luma, (9, 9), 2.0)
    gradient = cv2.magnitude(cv2.Sobel(smooth, cv2.CV_32F, 1, 0), cv2.Sobel(smooth, cv2.CV_32F, 0, 1))
    # the border's filters see mirrored pixels; leave it out
    inner = np.zeros(luma.shape, dtype=bool)
    inner[4:-4, 4:-4] = True
    if usable is not None:
        inner &= usable
    if not inner.any():
        return float("nan")
    flat = inner & (gradient <= np.quantile(gradient[inner], FLAT_QUANTILE))
    values = residual[flat].astype(np.float64)
    values -= np.median(values)
    sigma = values.std()
    for _ in range(5):
        sigma = values[np.abs(values) <= CLIP_SIGMAS * sigma].std()
    return float(sigma / BOX_RESIDUAL_GAIN)


def look_statistics(image_rgb_u8: np.ndarray, valid: np.ndarray | None = None) -> dict:
    """The look statistics of one (H, W, 3) uint8 RGB image (module docstring); keys
    :data:`STATISTICS`, floats. ``valid``: (H, W) bool, the pixels the lens images (None: all);
    brightness, clipped %, crushed % and noise are taken over them only."""
    image = np.asarray(image_rgb_u8)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {image.shape} {image.dtype}")
    if valid is None:
        valid = np.ones(image.shape[:2], dtype=bool)
    elif valid.shape != image.shape[:2] or not valid.any():
        raise ValueError(f"valid pixels {valid.shape} do not fit an image of {image.shape[:2]} (or are none)")
    luma = luma_of(image)
    clipped = (image >= 250).any(axis=2)
    crushed = luma <= 5.0
    rgb = image.astype(np.float64)
    rg = rgb[..., 0] - rgb[..., 1]
    yb = 0.5 * (rgb[..., 0] + rgb[..., 1]) - rgb[..., 2]
    colourfulness = np.hypot(rg.std(), yb.std()) + 0.3 * np.hypot(rg.mean(), yb.mean())
    return {
        "brightness": float(luma[valid].mean()),
        "clipped_pct": float(100.0 * clipped[valid].mean()),
        "crushed_pct": float(100.0 * crushed[valid].mean()),
        "noise_sigma": noise_sigma(luma, valid & ~(clipped | crushed)),
        "sharpness": float(cv2.Laplacian(luma, cv2.CV_32F, ksize=1).astype(np.float64).var()),
        "colourfulness": float(colourfulness),
    }


def image_files(folder: Path) -> list[Path]:
    """The images under ``folder`` (a run's ``images/`` only, when it has one), sorted."""
    if (folder / "images").is_dir():
        folder = folder / "images"
    return sorted(p for p in folder.rglob("*") if p.suffix.lower() in SUFFIXES and p.is_file())


def run_lenses(folder: Path) -> dict:
    """Camera name → :class:`~usdscene.document.model.Intrinsics` of the run whose output folder
    is ``folder`` or holds it (``OUT/images``, ``OUT/images/<camera>``; read from
    ``OUT/stage/scene.usda``); empty for other folders."""
    for root in (folder, folder.parent, folder.parent.parent):
        stage = root / "stage" / "scene.usda"
        if stage.is_file():
            from usdscene.render.stage_reader import read_stage_plan

            return {camera.name: camera.intrinsics for camera in read_stage_plan(stage).cameras}
    return {}


def image_valid_pixels(path: Path, shape: tuple[int, int], lenses: dict) -> np.ndarray | None:
    """The pixels that the lens of the camera of image ``path`` (``<camera>/<frame>.png``)
    images, at the image's size; None when the camera is not known."""
    intrinsics = lenses.get(path.parent.name)
    if intrinsics is None:
        return None
    from usdscene.lens import valid_pixels

    if (intrinsics.height_px, intrinsics.width_px) != shape:
        intrinsics = intrinsics.resized(shape[1], shape[0])
    return valid_pixels(intrinsics)


def folder_statistics(folder: Path) -> dict:
    """Mean of each statistic over the images of ``folder``, plus ``images`` (their count)."""
    files = image_files(folder)
    if not files:
        raise FileNotFoundError(f"{folder}: no PNG or JPEG images")
    lenses = run_lenses(folder)
    rows = []
    for path in files:
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if bgr is None:
            raise ValueError(f"{path}: not a readable image")
        rows.append(look_statistics(bgr[..., ::-1], image_valid_pixels(path, bgr.shape[:2], lenses)))
    out = {name: float(np.nanmean([row[name] for row in rows])) for name in STATISTICS}
    out["images"] = len(rows)
    return out


def format_table(results: dict[str, dict], markdown: bool = False) -> str:
    """The table of ``{label: folder_statistics(...)}``, plain or as Markdown."""
    columns = ["images"] + [HEADERS[s] for s in STATISTICS]
    lines = []
    if markdown:
        lines.append("| " + " | ".join(["run", *columns]) + " |")
        lines.append("|" + "---|" * (len(columns) + 1))
    else:
        lines.append(f"{'run':32s}" + "".join(f"{c:>14s}" for c in columns))
    for label, stats in results.items():
        cells = [f"{stats['images']:d}"] + [f"{stats[s]:.2f}" if s != "sharpness" else f"{stats[s]:.0f}"
                                             for s in STATISTICS]
        if markdown:
            lines.append("| " + " | ".join([label, *cells]) + " |")
        else:
            lines.append(f"{label:32s}" + "".join(f"{c:>14s}" for c in cells))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", help="FOLDER or LABEL=FOLDER")
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args(argv)
    results = {}
    for item in args.folders:
        label, _, path = item.rpartition("=") if "=" in item else (item, "", item)
        folder = Path(path)
        if not folder.is_dir():
            print(f"{item}: not a folder", file=sys.stderr)
            return 1
        try:
            results[label] = folder_statistics(folder)
        except (FileNotFoundError, ValueError) as exc:
            print(exc, file=sys.stderr)
            return 1
    print(format_table(results, markdown=args.markdown))
    return 0


if __name__ == "__main__":
    sys.exit(main())
