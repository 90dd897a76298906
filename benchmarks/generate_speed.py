"""How long the paper-size ``balanced`` cabin document takes to generate, validate and compose.

Writes the cabin setup of ``examples/aircraft_cabin/make_campaign.py`` into a temporary folder,
then times, each as one in-process call:

* ``generate``: ``usdscene.generate.sequences.generate_document`` (500 frames, 30 % of the seats
  taken), which includes reading the setup, writing the document and its report, and the
  placement check that the document composes;
* ``validate``: ``python -m usdscene validate DOC`` wall time (a fresh process, as a user runs it);
* ``compose``: ``usdscene.pipeline.compose_document`` (read, catalog, placement, USD layers).

Usage::

    python benchmarks/generate_speed.py [--frames 500] [--occupancy 0.3]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples" / "aircraft_cabin"))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=500)
    parser.add_argument("--occupancy", type=float, default=0.3)
    args = parser.parse_args(argv)

    from make_campaign import write_setup

    from usdscene.pipeline import compose_document
    from usdscene.generate.sequences import GenerateOptions, generate_document

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        setup = write_setup(tmp / "setup.openlabel.json", 640, 8)
        doc = tmp / "balanced.openlabel.json"
        t0 = time.perf_counter()
        result = generate_document(setup, doc, GenerateOptions(strategy="balanced", frames=args.frames, seed=2,
                                                               occupancy=args.occupancy))
        t_generate = time.perf_counter() - t0
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "usdscene", "validate", str(doc)], check=True,
                       stdout=subprocess.DEVNULL)
        t_validate = time.perf_counter() - t0
        t0 = time.perf_counter()
        _, composed = compose_document(doc, tmp / "stage")
        t_compose = time.perf_counter() - t0
        report = result.report
        print(f"document: {args.frames} frames, {report['objects']} objects, {len(report['places'])} places, "
              f"{report['instance_frames']} instance-frames, {doc.stat().st_size / 1e6:.1f} MB; "
              f"coverage {report['coverage']['covered']}/{report['coverage']['combinations']}")
        print(f"generate (incl. composability check): {t_generate:6.2f} s   (target < 10 s)")
        print(f"validate (new process):               {t_validate:6.2f} s   (target < 5 s)")
        print(f"compose ({len(composed.layers)} layers):                  {t_compose:6.2f} s   (target < 30 s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
