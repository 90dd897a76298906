"""Where the data shipped with usdscene lives: the asset library and the reusable USD layers.

In an installed wheel they are package data (``usdscene/assets``, ``usdscene/layers``); in a
source checkout (and an editable install) they are the repository's top-level ``assets/`` and
``layers/`` folders, which the build maps into the package (see ``pyproject.toml``).
"""

from __future__ import annotations

import os
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def shipped_folder(name: str) -> Path:
    """The shipped data folder ``name`` (``"assets"`` or ``"layers"``).

    Returns the installed package's copy when there is one, else the source checkout's
    top-level folder (which may not exist when neither is there; callers report that).
    """
    installed = _PACKAGE / name
    if installed.is_dir():
        return installed
    return _PACKAGE.parent / name


def default_asset_folder() -> Path:
    """The shipped asset library: ``$USDSCENE_ASSETS``, else the one installed with usdscene
    (``assets/`` of a source checkout)."""
    env = os.environ.get("USDSCENE_ASSETS")
    if env:
        return Path(env)
    return shipped_folder("assets")


def shipped_data_file(name: str) -> Path:
    """A data file shipped inside the package (``usdscene/data/<name>``: lens catalog, DORI
    table)."""
    return _PACKAGE / "data" / name
