"""The paper's dataset as a program: one camera setup, three generated sequence documents.

Writes, next to this script (or into ``--out``):

* ``setup.openlabel.json``: the cabin of ``make_documents.py`` (39 cameras, 16 ceiling lights and
  the sun, render settings, ROI rules) without any luggage or passenger;
* ``single_class.openlabel.json``: ``usdscene generate single-class`` (every class in every
  relation at every place where it fits, one class and relation per frame);
* ``balanced.openlabel.json``: ``usdscene generate balanced --frames 500`` (equal instance-frames
  per class, every fitting class × relation × place at least once), 30 % of the seats taken;
* ``appearance.openlabel.json``: ``usdscene generate appearance --frames 500`` (the same, with
  random appearance variants and colours);

each with its balance report ``<doc>.report.json``. The same commands by hand::

    python examples/aircraft_cabin/make_campaign.py --setup-only
    usdscene generate single-class --setup setup.openlabel.json -o single_class.openlabel.json --seed 1
    usdscene generate balanced --setup setup.openlabel.json -o balanced.openlabel.json \\
        --frames 500 --occupancy 0.3 --seed 2
    usdscene generate appearance --setup setup.openlabel.json -o appearance.openlabel.json \\
        --frames 500 --occupancy 0.3 --seed 3

Usage::

    python examples/aircraft_cabin/make_campaign.py [--frames 500] [--width 640] [--samples 8]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from make_documents import cabin_scene  # noqa: E402  (the example's cameras, lights, render settings)

from usdscene.cli import main as usdscene  # noqa: E402
from usdscene.converters.openlabel import write_document, write_openlabel  # noqa: E402

SEQUENCES = (  # (document, strategy, seed, takes --frames and --occupancy)
    ("single_class.openlabel.json", "single-class", 1, False),
    ("balanced.openlabel.json", "balanced", 2, True),
    ("appearance.openlabel.json", "appearance", 3, True),
)


def write_setup(path: Path, width_px: int, samples: int) -> Path:
    """The cabin setup: the example's scene without objects, relations or places."""
    scene = cabin_scene(frames=1, width_px=width_px, samples=samples, seed=7)
    setup = dataclasses.replace(scene, name="aircraft_cabin_setup", objects=(), relations=(), places=(),
                                description="Aircraft cabin camera setup of the paper: 39 cameras, "
                                            "16 ceiling lights and the sun; no luggage.")
    write_document(path, write_openlabel(setup))
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=500, help="frames of balanced and appearance (default 500)")
    parser.add_argument("--occupancy", type=float, default=0.3, help="fraction of seats taken (default 0.3)")
    parser.add_argument("--width", type=int, default=640, help="image width in px; height = 3/4 (default 640)")
    parser.add_argument("--samples", type=int, default=8, help="Cycles samples per pixel (default 8)")
    parser.add_argument("--out", type=Path, default=HERE, help="output folder (default: next to this script)")
    parser.add_argument("--setup-only", action="store_true", help="write the setup document only")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    setup = write_setup(args.out / "setup.openlabel.json", args.width, args.samples)
    print(f"wrote {setup}")
    if args.setup_only:
        return 0
    for name, strategy, seed, sized in SEQUENCES:
        command = ["generate", strategy, "--setup", str(setup), "-o", str(args.out / name), "--seed", str(seed)]
        if sized:
            command += ["--frames", str(args.frames), "--occupancy", str(args.occupancy)]
        status = usdscene(command)
        if status:
            return status
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
