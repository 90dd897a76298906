"""Rebuild every procedural asset of this folder and its ``catalog.json``.

    python assets/generate.py [--out FOLDER] [--rows N]

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
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from usdscene.assetgen.cabin import CabinConfig
    from usdscene.assetgen.library import build_library

    for path in build_library(args.out, CabinConfig(rows=args.rows)):
        logging.info("%s", path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
