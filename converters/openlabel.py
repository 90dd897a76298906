"""OpenLABEL 1.0.0 / VCD 4.3 ↔ :class:`usdscene.model.SceneSpec` (the public entry module).

::

    from usdscene.converters.openlabel import read_openlabel, write_openlabel, write_document

    scene = read_openlabel("scene.openlabel.json")           # DocumentError lists every problem
    write_document("out.openlabel.json", write_openlabel(scene))

The document vocabulary is described in ``docs/scene-format.md``. Implementation:
``openlabel_read`` (loading, VCD conversion, reading and checks the schema misses),
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
from usdscene.converters.openlabel_read import (
    EQUISOLID_KB_COEFFS,
    SCHEMA_VERSION,
    friendly_camera_rotation,
    load_document,
    load_with_provenance,
    read_loaded,
    read_openlabel,
)
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
