"""The ``usdscene`` command line.

``main(argv) -> int``: exit 0 on success, 1 when the input is bad (every problem printed as
``usdscene: error: <where>: <message>``, no traceback), 2 for bad usage (argparse), 130 when
interrupted. Each sub-command lives in ``usdscene/commands/<name>.py`` and defines ``NAME``,
``HELP``, ``ORDER``, ``add_arguments(parser)`` and ``run(args) -> int``; those modules import
only the standard library at module level so that ``--help`` stays fast, and import heavy
dependencies (pxr, bpy, cv2) inside ``run``.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys
from typing import Sequence

from usdscene import __version__
from usdscene.errors import UsdSceneError

PROG = "usdscene"


def _command_modules() -> list:
    import usdscene.commands as package

    modules = [importlib.import_module(f"{package.__name__}.{info.name}")
               for info in pkgutil.iter_modules(package.__path__) if not info.name.startswith("_")]
    return sorted(modules, key=lambda m: (getattr(m, "ORDER", 100), m.NAME))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Turn an OpenLABEL scene description into a layered USD stage, render every "
                    "camera with Blender Cycles and write exact labels.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more diagnostics on stderr (-vv for debug)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for module in _command_modules():
        cmd = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


def report_error(error: UsdSceneError, stream=None) -> None:
    """Print every problem of ``error`` as one ``usdscene: error: ...`` line."""
    stream = stream if stream is not None else sys.stderr
    for problem in error.problems:
        print(f"{PROG}: error: {problem}", file=stream)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help/--version exit 0, usage errors exit 2
        return int(exc.code or 0)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format=f"{PROG}: %(levelname)s: %(message)s")
    try:
        return int(args._run(args) or 0)
    except UsdSceneError as exc:
        report_error(exc)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; finished work is kept, re-run the same command to resume",
              file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
