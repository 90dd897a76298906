"""Shared fixtures. Tiers (markers) are described in docs/architecture.md.

The suite needs nothing outside the repository except the optional conformance corpus of
OpenLABEL files written by others: the official schema comes from the installed
``uai-openlabel`` package. The corpus is read from ``$USDSCENE_CONFORMANCE_DIR``, else from
``../shared/openlabel/conformance`` beside the checkout, and never copied into the repository.
Only tests that read it may skip, and only outside CI: with ``CI`` set they fail instead.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
CONFORMANCE_ENV = "USDSCENE_CONFORMANCE_DIR"
DEFAULT_CONFORMANCE = REPO.parent / "shared" / "openlabel" / "conformance"


@pytest.fixture(scope="session")
def openlabel_conformance() -> Path:
    """Folder of third-party OpenLABEL conformance files (see the module docstring)."""
    folder = Path(os.environ.get(CONFORMANCE_ENV) or DEFAULT_CONFORMANCE)
    if not any(folder.glob("*.json")):
        reason = (f"OpenLABEL conformance corpus not found at {folder} "
                  f"(set {CONFORMANCE_ENV} to the folder of third-party OpenLABEL files)")
        if os.environ.get("CI"):
            pytest.fail(reason + "; CI must have it")
        pytest.skip(reason)
    return folder


@pytest.fixture(scope="session")
def openlabel_schema_path() -> Path:
    """The official OpenLABEL 1.0.0 JSON schema shipped by the installed ``uai-openlabel``."""
    from usdscene.converters.openlabel import packaged_schema_path

    path = packaged_schema_path()
    assert path is not None, "uai-openlabel is a runtime dependency and ships the official schema"
    return path
