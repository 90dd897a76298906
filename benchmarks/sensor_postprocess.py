"""CPU milliseconds of the sensor post-process per 640x480 image: the 8-bit chain
(usdscene.sensor.pipeline.apply_sensor) for each effect alone and a typical combination, and the
whole linear chain (process_image: metering, auto exposure, WDR tone curve, lens blur, noise,
unsharp mask, 4:2:0 chroma, compression) of each camera profile.

    python benchmarks/sensor_postprocess.py [--repeat 50]

The image is a rendered-looking 640x480 sRGB picture (smooth gradients plus texture). CPU time
of the calling thread (time.thread_time), robust on a shared machine; median and best.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from usdscene.document.camera_profiles import PROFILES
from usdscene.document.imaging import Sensor, image_seed, profile_sensor
from usdscene.sensor.pipeline import apply_sensor, process_image

CASES = {
    "exposure bias +0.5 EV": Sensor(exposure_bias_ev=0.5),
    "vignetting 0.3": Sensor(vignetting=0.3),
    "noise ISO 1600": Sensor(iso=1600),
    "JPEG quality 75": Sensor(compression="jpeg", quality=75),
    "H.264-like quality 40": Sensor(compression="h264_like", quality=40),
    "IR night + noise ISO 3200": Sensor(ir_night=True, iso=3200),
    "typical: noise ISO 1600 + vignetting 0.3 + JPEG 75": Sensor(iso=1600, vignetting=0.3, compression="jpeg", quality=75),
    "everything: bias, vignetting, noise, IR, JPEG": Sensor(exposure_bias_ev=0.3, vignetting=0.3, iso=3200,
                                                              ir_night=True, compression="jpeg", quality=60),
}


def test_image(height: int = 480, width: int = 640) -> np.ndarray:
    """(H, W, 3) uint8 RGB: gradients with a fine texture, like a render."""
    rs = np.random.default_rng(0)
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    base = np.stack([xs / width, ys / height, 0.5 + 0.3 * np.sin(xs / 37.0) * np.cos(ys / 23.0)], axis=-1)
    texture = rs.normal(0.0, 0.03, (height, width, 1)).astype(np.float32)
    return np.clip((base + texture) * 255.0, 0, 255).astype(np.uint8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=50)
    args = parser.parse_args()
    image = test_image()
    print(f"640x480, {args.repeat} runs each, load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} CPUs")
    print(f"{'effect':55s} {'median ms':>9s} {'best ms':>8s}")
    for name, sensor in CASES.items():
        apply_sensor(image, sensor, np.random.default_rng(0))  # tables and caches built once
        times = []
        for frame in range(args.repeat):
            rng = np.random.default_rng(image_seed(0, "bench", frame))
            started = time.thread_time()
            apply_sensor(image, sensor, rng)
            times.append(time.thread_time() - started)
        print(f"{name:55s} {1000 * np.median(times):9.2f} {1000 * min(times):8.2f}")
    # the linear chain starts from the float render: the same picture decoded to linear light
    linear = ((image.astype(np.float32) / 255.0) ** 2.2).astype(np.float32)
    for name in PROFILES:
        sensor = profile_sensor(name)
        process_image(linear, sensor, np.random.default_rng(0))
        times = []
        for frame in range(args.repeat):
            rng = np.random.default_rng(image_seed(0, "bench", frame))
            started = time.thread_time()
            process_image(linear, sensor, rng)
            times.append(time.thread_time() - started)
        print(f"{'profile ' + name + ' (whole linear chain)':55s} {1000 * np.median(times):9.2f} {1000 * min(times):8.2f}")


if __name__ == "__main__":
    main()
