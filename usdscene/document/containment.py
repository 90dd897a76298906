"""Which folders usdscene may read: a scene document never makes it read the rest of the disk.

A document names asset catalogs (``metadata.usdscene.asset_paths``), a catalog names USD files
(``usd`` entries), and a USD file names more files through its composition arcs (sublayers,
references, payloads). Each of those paths is resolved (``..`` and symbolic links followed)
and must lie inside one of the *reading roots*:

- the folder of the scene document,
- the working folder (where the user runs usdscene),
- the shipped asset library (:func:`usdscene.shipped.default_asset_folder`),
- the folders the user consented to: ``--asset-path DIR`` on the command line, or the
  ``USDSCENE_ASSET_PATH`` environment variable (folders separated by ``os.pathsep``),
- and, for the files a catalog names, the catalog folders that passed this check.

Anything else is refused with a problem naming the path, what named it and the folder to
consent to. Paths are checked before the file is opened, so a refused file is never read.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Iterable, Sequence

from usdscene.errors import Problem

ASSET_PATH_ENV = "USDSCENE_ASSET_PATH"


def consented_folders() -> tuple[Path, ...]:
    """Folders the user allowed with ``USDSCENE_ASSET_PATH`` (the CLI's ``--asset-path``
    adds to it), resolved; empty entries are ignored."""
    text = os.environ.get(ASSET_PATH_ENV, "")
    return tuple(Path(p).resolve() for p in text.split(os.pathsep) if p.strip())


def reading_roots(document_folder: str | os.PathLike | None,
                  consented: Iterable[str | os.PathLike] = ()) -> tuple[Path, ...]:
    """The folders a scene document may make usdscene read (see the module docstring).

    Args:
        document_folder: folder of the scene document, or None for none.
        consented: more folders the caller vouches for (e.g. given on the command line);
            those of ``USDSCENE_ASSET_PATH`` are always added.

    Returns:
        Resolved folders, duplicates removed, in a stable order.
    """
    from usdscene.shipped import default_asset_folder

    folders = [Path.cwd(), default_asset_folder(), *(Path(p) for p in consented)]
    if document_folder is not None:
        folders.insert(0, Path(document_folder))
    roots: list[Path] = []
    for folder in [*(f.resolve() for f in folders), *consented_folders()]:
        if folder not in roots:
            roots.append(folder)
    return tuple(roots)


def is_inside(path: str | os.PathLike, roots: Sequence[Path]) -> bool:
    """Whether ``path``, resolved (``..`` and symbolic links followed), lies in one of ``roots``
    (resolved folders)."""
    resolved = Path(path).resolve()
    return any(resolved == root or root in resolved.parents for root in roots)


def outside_problem(where: str, path: str | os.PathLike, what: str, *,
                    anchor: str | os.PathLike | None = None) -> Problem:
    """The problem for a path outside every reading root: names the path as written, where
    it resolves and the folder to consent to.

    Args:
        where: JSON path or file that named the path.
        path: the path as written.
        what: what it is (``"asset folder"``, ``"asset file"``, ``"USD composition arc"``).
        anchor: folder a relative ``path`` is relative to (default: the working folder).
    """
    resolved = (Path(anchor) / path if anchor is not None else Path(path)).resolve()
    shown = repr(str(path)) if str(path) == str(resolved) else f"{str(path)!r} (resolved {str(resolved)!r})"
    consent = resolved if what == "asset folder" else resolved.parent
    return Problem(where, f"{what} {shown} lies outside the document's folder, the working folder and "
                          f"the asset folders; give --asset-path {str(consent)!r} "
                          f"(or add it to ${ASSET_PATH_ENV}) to allow reading it")


def usd_dependency_problems(usd_path: str | os.PathLike, roots: Sequence[Path]) -> list[Problem]:
    """Check every composition arc (sublayer, reference, payload) of a USD file, recursively,
    against ``roots`` before opening the file it names.

    Args:
        usd_path: the USD file (itself already checked by the caller).
        roots: resolved folders the files may lie in.

    Returns:
        One problem per arc that leaves ``roots`` or names a file that cannot be opened,
        naming the layer that holds the arc; empty when all are inside.
    """
    problems: list[Problem] = []
    seen: set[Path] = set()
    pending = [Path(usd_path).resolve()]
    while pending:
        path = pending.pop()
        if path in seen:
            continue
        seen.add(path)
        try:
            stat = path.stat()
            arcs = _layer_arcs(path, stat.st_mtime_ns, stat.st_size)
        except (OSError, ValueError) as exc:
            problems.append(Problem(str(path), f"cannot open USD layer: {exc}"))
            continue
        for arc, target in arcs:
            if not is_inside(target, roots):
                problems.append(outside_problem(str(path), arc, "USD composition arc", anchor=path.parent))
            elif Path(target).resolve() not in seen:
                pending.append(Path(target).resolve())
    return problems


@functools.lru_cache(maxsize=1024)
def _layer_arcs(path: Path, mtime_ns: int, size: int) -> tuple[tuple[str, str], ...]:
    """(arc as written, absolute path) of every sublayer, reference and payload of one layer.

    Cached by the file's modification time and size (parsing a large asset layer costs tens
    of milliseconds, and every composition checks the same assets again).

    Raises:
        ValueError: the layer cannot be opened (USD's reason, on one line).
    """
    from pxr import Sdf

    from usdscene.errors import usd_error_text

    try:
        layer = Sdf.Layer.FindOrOpen(str(path))
    except Exception as exc:  # pxr raises Tf.ErrorException for unreadable layers
        raise ValueError(usd_error_text(exc)) from None
    if layer is None:
        raise ValueError("not a USD layer")
    return tuple((arc, layer.ComputeAbsolutePath(arc))
                 for arc in sorted(layer.GetCompositionAssetDependencies()) if arc)
