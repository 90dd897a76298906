"""How big the wheel is, and what the baked people take of it.

    python benchmarks/wheel_size.py [--before CHECKOUT]

Builds the wheel of this checkout (``pip wheel . --no-deps``, into a temporary folder) and
prints its size and, for every shipped ``people/*.usda``, its size as text and compressed in
the wheel. ``--before`` builds another checkout's wheel too (e.g. one before the people) and
prints the growth.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def build_wheel(checkout: Path, out: Path) -> Path:
    """The wheel of ``checkout`` built into ``out`` (pip, no dependencies)."""
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(checkout), "--no-deps", "-q", "-w", str(out)],
                   check=True)
    return next(out.glob("*.whl"))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="another checkout to compare with")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        wheel = build_wheel(HERE, Path(tmp) / "this")
        size = wheel.stat().st_size / 1e6
        print(f"wheel of this checkout: {size:.2f} MB")
        with zipfile.ZipFile(wheel) as z:
            for info in z.infolist():
                if "/people/" in info.filename and info.filename.endswith(".usda"):
                    print(f"  {info.filename}: {info.file_size / 1e6:.1f} MB of text, "
                          f"{info.compress_size / 1e6:.2f} MB compressed")
        if args.before:
            before = build_wheel(args.before.resolve(), Path(tmp) / "before").stat().st_size / 1e6
            print(f"wheel of {args.before}: {before:.2f} MB; this one {size - before:+.2f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
