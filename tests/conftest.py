"""Shared fixtures. Tiers (markers) are described in docs/architecture.md."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SHARED_OPENLABEL = REPO.parent / "shared" / "openlabel"


@pytest.fixture(scope="session")
def openlabel_reference() -> Path:
    """Folder with the official OpenLABEL schema and third-party conformance files.

    They are read from ``../shared/openlabel`` beside the checkout and never copied into the
    repository; tests that need them skip with this reason when the folder is absent.
    """
    if not (SHARED_OPENLABEL / "schema").is_dir():
        pytest.skip(f"OpenLABEL reference folder not found at {SHARED_OPENLABEL}")
    return SHARED_OPENLABEL


@pytest.fixture(scope="session")
def openlabel_schema_path(openlabel_reference: Path) -> Path:
    return openlabel_reference / "schema" / "openlabel_json_schema-v1.0.0.json"
