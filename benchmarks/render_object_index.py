"""What Cycles' object-index pass does on pixels shared by two objects (measured, not assumed).

Scene: flat emissive spheres (no lights), so the beauty pass of a pixel is the coverage-weighted
mix of the object colours. Prints:

1. whether the mask changes with the sample count (it is written from the first sample only);
2. at object edges, how often the mask id is the object covering most of the pixel (coverage
   from a 256-sample beauty render of the same pixels);
3. which id a semi-transparent object in front of an opaque one gets, for several opacities.

Run: python benchmarks/render_object_index.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import cv2
import numpy as np

from usdscene.document import output_layout as layout
from usdscene.document.model import Camera, Intrinsics, LensModel, Pose
from usdscene.render.driver import render
from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
CAM = Camera("cam", Intrinsics(LensModel.PERSPECTIVE, 160, 120, 150.0, 150.0, 79.5, 59.5),
             Pose.from_rotation_translation(R, [-4.0, 0.0, 0.0]))


def _render(spheres, samples, root: Path):
    stage = write_synthetic_stage(SyntheticScene(cameras=(CAM,), spheres=spheres), root / "stage")
    out = root / f"out{samples}"
    render(stage, out, settings_override={"samples": samples, "denoise": False}, progress=False)
    image = cv2.imread(str(layout.image_path(out, "cam", 0)))[:, :, ::-1].astype(float) / 255
    mask = cv2.imread(str(layout.mask_path(out, "cam", 0)), cv2.IMREAD_UNCHANGED)
    return image, mask


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        # Red sphere partly in front of a green one, on black.
        spheres = (SphereSpec("red", (0.0, -0.3, 0.0), 0.5, (1.0, 0.0, 0.0), 1),
                   SphereSpec("green", (1.0, 0.3, 0.1), 0.6, (0.0, 1.0, 0.0), 2))
        masks = {}
        for samples in (1, 4, 16, 256):
            image, masks[samples] = _render(spheres, samples, root / f"aa{samples}")
        same = all(np.array_equal(masks[1], masks[s]) for s in (4, 16, 256))
        print(f"mask identical at 1, 4, 16 and 256 samples per pixel: {same}")
        # Coverage from the 256-sample beauty (sRGB → linear): red = object 1, green = object 2.
        lin = np.where(image <= 0.04045, image / 12.92, ((image + 0.055) / 1.055) ** 2.4)
        cover = np.stack([1 - lin[..., 0] - lin[..., 1], lin[..., 0], lin[..., 1]], -1)  # bg, red, green
        edge = (cover.max(-1) < 0.98)
        majority = cover.argmax(-1)
        agree = (masks[256][edge] == majority[edge]).mean()
        print(f"edge pixels (no object covers ≥ 98 %): {int(edge.sum())}; mask id = majority object in "
              f"{100 * agree:.1f} %")
        mixed = cover[edge][np.arange(edge.sum()), masks[256][edge].astype(int)]
        print(f"coverage of the object named by the mask at edge pixels: median {np.median(mixed):.2f}, "
              f"min {mixed.min():.2f}")
        # Transparency: a sphere of opacity a in front of an opaque one.
        for opacity in (0.2, 0.45, 0.55, 0.8, 1.0):
            spheres = (SphereSpec("glass", (-0.5, 0.0, 0.0), 0.4, (1.0, 0.0, 0.0), 1, opacity=opacity),
                       SphereSpec("wall", (1.0, 0.0, 0.0), 1.0, (0.0, 1.0, 0.0), 2))
            _, mask = _render(spheres, 4, root / f"t{opacity}")
            yy, xx = np.mgrid[0:120, 0:160]
            overlap = mask[(yy - 59.5) ** 2 + (xx - 79.5) ** 2 < 12 ** 2]
            front = (overlap == 1).mean()
            print(f"opacity {opacity:.2f} in front of an opaque object: {100 * front:.0f} % of the overlap "
                  f"pixels carry the front id, {100 * (overlap == 2).mean():.0f} % the id behind")

if __name__ == "__main__":
    main()
