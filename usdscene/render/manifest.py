"""``out/manifest.json``: which (frame, camera) pairs are finished, for resume. Pure.

Format::

    {
      "format": "usdscene-render-manifest/1",
      "fingerprint": "<sha256 of what determines the pixels>",
      "versions": {"usdscene": ..., "blender": ...},
      "done": {"<camera>": {"<frame>": {"render_s": ..., "render_cpu_s": ..., "post_s": ...}}},
      "timings": {"wall_s": ..., "render_s": ...}
    }

A pair counts as finished when the manifest lists it *and* both its PNG files exist. The
fingerprint covers the stage file contents, the cameras and the render settings: when it
changes, earlier results no longer describe the scene and every pair is rendered again.
Written atomically (temp file + rename) after every finished pair, so a killed run loses at
most the pair in flight.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from usdscene.document import output_layout as layout
from usdscene.files import write_json_atomic

FORMAT = "usdscene-render-manifest/1"


def fingerprint(payload: Any) -> str:
    """sha256 hex digest of a JSON-serialisable payload (canonical key order)."""
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass
class Manifest:
    """The render manifest of one output folder (a lifecycle object: load, mark, save)."""

    out_dir: Path
    fingerprint: str = ""
    done: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    versions: dict[str, str] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    # render.depth of the run (None = off): a pair is finished only with its depth image too
    depth_format: str | None = None

    @property
    def path(self) -> Path:
        """The manifest file of the output folder (``out/manifest.json``)."""
        return Path(self.out_dir) / layout.MANIFEST_FILE

    @staticmethod
    def load(out_dir: Path, expected_fingerprint: str) -> "Manifest":
        """Read the manifest of ``out_dir``; a missing, unreadable or stale one starts empty."""
        manifest = Manifest(Path(out_dir), expected_fingerprint)
        try:
            data = json.loads(manifest.path.read_text())
        except (FileNotFoundError, json.JSONDecodeError, UnicodeDecodeError):
            return manifest
        if data.get("format") != FORMAT or data.get("fingerprint") != expected_fingerprint:
            return manifest
        manifest.done = {str(c): {str(f): dict(v) for f, v in frames.items()}
                         for c, frames in (data.get("done") or {}).items()}
        manifest.timings = dict(data.get("timings") or {})
        return manifest

    def is_done(self, frame: int, camera: str) -> bool:
        """Whether the pair is listed as finished and its image and mask files exist."""
        if str(frame) not in self.done.get(camera, {}):
            return False
        return (layout.image_path(self.out_dir, camera, frame).is_file()
                and layout.mask_path(self.out_dir, camera, frame).is_file()
                and (self.depth_format is None
                     or layout.depth_path(self.out_dir, camera, frame, self.depth_format).is_file()))

    def mark_done(self, frame: int, camera: str, timing: dict[str, float]) -> None:
        """List the pair as finished with its timings (seconds, rounded to µs); :meth:`save` writes it."""
        self.done.setdefault(camera, {})[str(frame)] = {k: round(float(v), 6) for k, v in timing.items()}

    def save(self) -> None:
        """Write the manifest atomically."""
        write_json_atomic(self.path, {
            "format": FORMAT,
            "fingerprint": self.fingerprint,
            "versions": self.versions,
            "done": self.done,
            "timings": self.timings,
        })
