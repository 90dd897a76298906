"""Render seconds of the car park example under a black world, a physical sky, a sky whose
strength changes every frame (what domain randomisation writes), the same sky baked into an
HDRI, a plain colour as bright as the sky and a dim HDRI, one camera.

    python benchmarks/world_render_cost.py OUT [--frames 3] [--samples 8] [--width 640]
                                           [--compare-to EARLIER_OUT]

Each variant renders frames 0..N-1 of ``pole_north`` in one worker (640x480, the document's
8 samples + denoising by default). Printed per variant: the first image's render CPU seconds
(all threads; it includes building the world: Blender bakes the sky's texture and Cycles the
world's importance map when the world first syncs), the mean of the others, both as a ratio to
the black world, the later images' wall seconds, the images' mean sRGB level, their mean
absolute difference from the sky's images (levels) and, with ``--compare-to``, from the same
variant's images in an earlier run's OUT (what a change of render settings did to the look;
the difference between two equally good renders is their noise).

The two worlds that carry the sky's light without a sky node: the sky rendered alone by Cycles
into a 1024x512 equirectangular image (``usdscene.render.blender.world.bake_world``) and used as the
world's HDRI, and one colour, the sky's radiance averaged over the upper hemisphere weighted by
the cosine to the zenith (a horizontal surface open to it receives the sky's irradiance).
"""

from __future__ import annotations

import argparse
import copy
import json
import os
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
CAR_PARK = REPO / "examples" / "car_park"


def document(world: dict | None, frames: int, samples: int, width: int) -> dict:
    doc = json.loads((CAR_PARK / "car_park.openlabel.json").read_text())
    setup = json.loads((CAR_PARK / "setup.openlabel.json").read_text())
    body = doc["openlabel"]
    block = body["metadata"]["usdscene"]
    block["asset_paths"] = [str(CAR_PARK / "assets")]
    block["render"] = dict(block["render"], samples=samples)
    block["frame_range"] = {"frame_start": 0, "frame_end": frames - 1}
    block["exports"] = []
    block.pop("world", None)
    if world is not None:
        block["world"] = world
    del body["coordinate_systems"]
    stream = copy.deepcopy(setup["openlabel"]["streams"]["pole_north"])
    stream["stream_properties"]["usdscene"]["resolution_px"] = [width, width * 3 // 4]
    body["streams"] = {"pole_north": stream}
    return doc


def bake_sky(sky_document: Path, hdri: Path) -> np.ndarray:
    """Render the sky of ``sky_document`` alone into the 1024x512 equirectangular ``hdri``;
    returns it as (512, 1024, 3) float32 linear RGB, the zenith in row 0."""
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.document.imaging import world_stage_json
    from usdscene.render.driver import run_job
    from usdscene.render.job import BakeWorldJob

    world_job = json.loads(world_stage_json(read_openlabel(sky_document)))
    run_job(BakeWorldJob(world=world_job, frame=0, size_px=(1024, 512), samples=4, out=str(hdri)), "sky bake")
    return cv2.imread(str(hdri), cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float32)


def sky_irradiance_radiance(equirect: np.ndarray) -> list[float]:
    """The uniform radiance (linear RGB) that gives a horizontal surface the irradiance of the
    equirectangular ``equirect`` (zenith in row 0): ``(1/π) ∫ L cos θ dω`` over the upper
    hemisphere."""
    height, width = equirect.shape[:2]
    theta = (np.arange(height) + 0.5) / height * np.pi  # from the zenith
    weights = np.where(theta < np.pi / 2, np.cos(theta) * np.sin(theta), 0.0) * (np.pi / height) * (2 * np.pi / width)
    return [float(v) for v in np.einsum("h,hwc->c", weights, equirect) / np.pi]


def main() -> None:
    from usdscene.pipeline import RunOptions, run_pipeline

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--compare-to", type=Path, help="an earlier run's OUT")
    args = parser.parse_args()
    os.environ["USDSCENE_ASSET_PATH"] = str(CAR_PARK)
    args.out.mkdir(parents=True, exist_ok=True)
    sky = {"sky": "nishita"}
    names = ["black world (no world block)", "physical sky (nishita)", "sky, strength per frame",
             "sky baked to HDRI 1024x512", "plain colour, sky's irradiance", "HDRI 128x128 (dim)"]
    folders = {name: args.out / f"variant{i}" for i, name in enumerate(names)}
    for folder in folders.values():
        folder.mkdir(parents=True, exist_ok=True)
    sky_document = folders["physical sky (nishita)"] / "scene.openlabel.json"
    sky_document.write_text(json.dumps(document(sky, args.frames, args.samples, args.width)))
    # In each document's folder: a readable place for its HDRI.
    baked = bake_sky(sky_document, folders["sky baked to HDRI 1024x512"] / "sky.hdr")
    colour = sky_irradiance_radiance(baked)
    dim = folders["HDRI 128x128 (dim)"] / "sky.hdr"
    rows = np.linspace(1.0, 0.2, 64, dtype=np.float32)[:, None, None]
    cv2.imwrite(str(dim), np.concatenate([np.broadcast_to(rows * np.array([0.9, 0.6, 0.4], np.float32), (64, 128, 3)),
                                          np.full((64, 128, 3), 0.15, np.float32)], axis=0))
    variants = {
        names[0]: None,
        names[1]: sky,
        names[2]: {**sky, "per_frame": {str(f): {"strength": 0.8 + 0.1 * f} for f in range(args.frames)}},
        names[3]: {"hdri": "sky.hdr"},
        names[4]: {"color_rgb": colour},
        names[5]: {"hdri": "sky.hdr"},
    }
    results, images = {}, {}
    for name, world in variants.items():
        folder = folders[name]
        path = folder / "scene.openlabel.json"
        path.write_text(json.dumps(document(world, args.frames, args.samples, args.width)))
        run_pipeline(path, folder / "out", RunOptions(exports=[]), progress=False)
        done = json.loads((folder / "out" / "manifest.json").read_text())["done"]["pole_north"]
        cpu = [done[str(f)]["render_cpu_s"] for f in range(args.frames)]
        wall = [done[str(f)]["render_s"] for f in range(args.frames)]
        results[name] = (cpu[0], float(np.mean(cpu[1:])), float(np.mean(wall[1:])))
        images[name] = read_images(folder / "out", args.frames)
    base_first, base_rest, _ = results[names[0]]
    print(f"car park pole_north, {args.width}x{args.width * 3 // 4}, {args.samples} samples + denoising, "
          f"{args.frames} frames, load average {os.getloadavg()[0]:.1f}")
    print(f"plain colour (linear RGB): {colour[0]:.4f} {colour[1]:.4f} {colour[2]:.4f}")
    print(f"{'world':32s} {'first cpu s':>11s} {'ratio':>6s} {'later cpu s':>11s} {'ratio':>6s} {'wall s':>6s} "
          f"{'level':>6s} {'vs sky':>6s}" + (f" {'vs earlier':>10s}" if args.compare_to else ""))
    for i, (name, (first, rest, rest_wall)) in enumerate(results.items()):
        level = images[name].mean()
        difference = np.abs(images[name] - images[names[1]]).mean()
        line = (f"{name:32s} {first:11.2f} {first / base_first:6.2f} {rest:11.2f} {rest / base_rest:6.2f} "
                f"{rest_wall:6.2f} {level:6.1f} {difference:6.1f}")
        if args.compare_to:
            earlier = read_images(args.compare_to / f"variant{i}" / "out", args.frames)
            line += f" {np.abs(images[name] - earlier).mean():10.2f}"
        print(line)


def read_images(out: Path, frames: int) -> np.ndarray:
    """(frames, H, W, 3) float32: ``pole_north``'s images of a run's output folder."""
    from usdscene.document.output_layout import image_path

    return np.stack([cv2.imread(str(image_path(out, "pole_north", f))).astype(np.float32) for f in range(frames)])


if __name__ == "__main__":
    main()
