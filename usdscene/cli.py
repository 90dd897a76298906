"""The ``usdscene`` command line.

``main(argv) -> int``: exit 0 on success, 1 when the input is bad (every problem printed as
``usdscene: error: <where>: <message>``, no traceback), 2 for bad usage (argparse), 130 when
interrupted. An operating-system error that no library function turned into a
:class:`~usdscene.errors.UsdSceneError` (a file that cannot be read or written, a full disk)
is the last resort: one line naming the path and the cause, exit 1. Each sub-command lives in ``usdscene/commands/<name>.py`` and defines ``NAME``,
``HELP``, ``ORDER``, ``add_arguments(parser)`` and ``run(args) -> int``; those modules import
only the standard library at module level so that ``--help`` stays fast, and import heavy
dependencies (pxr, bpy, cv2) inside ``run``.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import os
import pkgutil
import signal
import sys
import threading
from typing import Sequence

from usdscene import __version__
from usdscene.errors import Problem, UsdSceneError

PROG = "usdscene"


def _command_modules() -> list:
    import usdscene.commands as package

    modules = [importlib.import_module(f"{package.__name__}.{info.name}")
               for info in pkgutil.iter_modules(package.__path__) if not info.name.startswith("_")]
    return sorted(modules, key=lambda m: (getattr(m, "ORDER", 100), m.NAME))


def build_parser() -> argparse.ArgumentParser:
    """The ``usdscene`` argument parser, with one sub-command per module of
    :mod:`usdscene.commands`, ordered by their ``ORDER``."""
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
        cmd.add_argument("--asset-path", action="append", default=[], metavar="DIR",
                         help="allow reading asset catalogs and USD files in DIR although it lies "
                              "outside the document's folder and the working folder (repeatable; "
                              "also $USDSCENE_ASSET_PATH)")
        cmd.set_defaults(_run=module.run)
    return parser


def report_error(error: UsdSceneError, stream=None) -> None:
    """Print every problem of ``error`` as one ``usdscene: error: ...`` line."""
    stream = stream if stream is not None else sys.stderr
    for problem in error.problems:
        print(f"{PROG}: error: {problem}", file=stream)


@contextlib.contextmanager
def _consented_asset_paths(folders: Sequence[str]):
    """``--asset-path``: the folders join ``$USDSCENE_ASSET_PATH`` for this run (render worker
    processes inherit it), and the variable is restored afterwards."""
    from usdscene.document.containment import ASSET_PATH_ENV

    before = os.environ.get(ASSET_PATH_ENV)
    if folders:
        absolute = [os.path.abspath(f) for f in folders]
        os.environ[ASSET_PATH_ENV] = os.pathsep.join([*absolute, *([before] if before else [])])
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(ASSET_PATH_ENV, None)
        else:
            os.environ[ASSET_PATH_ENV] = before


def _file_size_limit_as_error() -> None:
    """Turn a file size limit (``ulimit -f``) into a write error instead of a silent kill.

    By default the kernel kills a process with SIGXFSZ when a write passes the limit; ignored,
    the write fails with EFBIG, which becomes a readable error naming the file. Render worker
    processes inherit the ignored disposition.
    """
    if hasattr(signal, "SIGXFSZ") and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``usdscene`` with ``argv`` (default: ``sys.argv[1:]``); returns the exit status:
    0 done, 1 bad data or a failed job (one message per problem, no traceback), 2 bad usage."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help/--version exit 0, usage errors exit 2
        return int(exc.code or 0)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format=f"{PROG}: %(levelname)s: %(message)s")
    _file_size_limit_as_error()
    try:
        with _consented_asset_paths(args.asset_path):
            return int(args._run(args) or 0)
    except UsdSceneError as exc:
        report_error(exc)
        return 1
    except OSError as exc:  # a read or write no library function anticipated
        from usdscene.files import os_problem

        report_error(UsdSceneError([os_problem(exc)]))
        return 1
    except MemoryError:
        report_error(UsdSceneError([Problem("", "out of memory")]))
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; finished work is kept, re-run the same command to resume",
              file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
