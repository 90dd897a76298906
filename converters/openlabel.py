"""OpenLABEL 1.0.0 / VCD 4.3 ↔ :class:`usdscene.document.model.SceneSpec` (the public entry module).

::

    from usdscene.converters.openlabel import read_openlabel, write_openlabel, write_document

    scene = read_openlabel("scene.openlabel.json")           # DocumentError lists every problem
    write_document("out.openlabel.json", write_openlabel(scene))

The document vocabulary is described in ``docs/scene-format.md``. Implementation:
``openlabel_load`` (files, JSON, VCD 4.3 → OpenLABEL, provenance), ``openlabel_read`` (the reader
that ties the sections together: ``openlabel_metadata``, ``openlabel_cameras`` with
``openlabel_poses`` and ``openlabel_intrinsics``, ``openlabel_objects``, ``openlabel_relations``),
``openlabel_write`` (the normal form), ``openlabel_checks`` (the official schema),
``openlabel_values`` (value readers and pose encodings).
"""

from usdscene.converters.openlabel_checks import (
    SCHEMA_ENV,
    default_schema_path,
    packaged_schema_path,
    schema_path_from_env,
    schema_problems,
)
from usdscene.converters.openlabel_intrinsics import EQUISOLID_KB_COEFFS
from usdscene.converters.openlabel_load import SCHEMA_VERSION, load_document, load_with_provenance
from usdscene.converters.openlabel_poses import friendly_camera_rotation
from usdscene.converters.openlabel_read import read_loaded, read_openlabel
from usdscene.converters.openlabel_write import write_document, write_openlabel

__all__ = [
    "EQUISOLID_KB_COEFFS",
    "SCHEMA_ENV",
    "SCHEMA_VERSION",
    "friendly_camera_rotation",
    "load_document",
    "load_with_provenance",
    "read_loaded",
    "read_openlabel",
    "schema_path_from_env",
    "default_schema_path",
    "packaged_schema_path",
    "schema_problems",
    "write_document",
    "write_openlabel",
]
