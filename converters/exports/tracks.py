"""Track identity and ground positions of a moving sequence, shared by every export. Pure (numpy).

A moving sequence is a document that states its frame rate (``metadata.usdscene.fps``); each of
its objects is one track for the whole sequence, in every camera. Exports that need integers
(MOTChallenge, WILDTRACK, the ``track_id`` of COCO annotations) number the tracks by one rule:
:data:`ID_RULE`.
"""

from __future__ import annotations

import numpy as np

from usdscene.errors import OutputError

ID_RULE = ("objects that are neither lights nor places, ordered by uid (integer uids by value, then the "
           "others by text), numbered 1, 2, ... in that order")
NOT_TRACKED = frozenset({"light", "place"})
GROUND_POSITION = "ground_position_m"
"""Per-frame ``vec`` object data: where a moving object stands (world metres), by ``generate tracks``."""


def document_fps(document: dict) -> float | None:
    """``metadata.usdscene.fps`` of a document (None when it states none)."""
    meta = (document.get("openlabel", {}).get("metadata") or {}).get("usdscene") or {}
    fps = meta.get("fps")
    return float(fps) if isinstance(fps, (int, float)) and not isinstance(fps, bool) and fps > 0 else None


def track_ids(document: dict) -> dict[str, int]:
    """uid → integer track id of every tracked object of a document (see the module docstring)."""
    objects = document.get("openlabel", {}).get("objects", {}) or {}
    uids = [uid for uid, element in objects.items() if (element or {}).get("type") not in NOT_TRACKED]
    ordered = sorted(uids, key=lambda u: (0, int(u), "") if u.lstrip("-").isdigit() else (1, 0, u))
    return {uid: k + 1 for k, uid in enumerate(ordered)}


def require_tracks(document: dict, what: str) -> float:
    """The document's frame rate, or an :class:`OutputError` saying it is no moving sequence."""
    fps = document_fps(document)
    if fps is None:
        raise OutputError(f"the {what} export needs tracks: the document states no frame rate "
                          "(metadata.usdscene.fps), so its frames are independent situations, not a "
                          "sequence in time; generate one with `usdscene generate tracks`",
                          where="metadata.usdscene.fps")
    return fps


def ground_positions(document: dict) -> dict[int, dict[str, np.ndarray]]:
    """frame → uid → (3,) ground position (world metres) from the per-frame object data."""
    out: dict[int, dict[str, np.ndarray]] = {}
    for key, frame in (document.get("openlabel", {}).get("frames", {}) or {}).items():
        for uid, entry in ((frame or {}).get("objects", {}) or {}).items():
            for item in ((entry or {}).get("object_data", {}) or {}).get("vec", []):
                if item.get("name") == GROUND_POSITION:
                    out.setdefault(int(key), {})[uid] = np.asarray(item["val"], dtype=np.float64)
    return out
