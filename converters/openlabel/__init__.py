"""OpenLABEL 1.0.0 / VCD 4.3 ↔ :class:`usdscene.document.model.SceneSpec` (the public entry module).

::

    from usdscene.converters.openlabel import read_openlabel, write_openlabel, write_document

    scene = read_openlabel("scene.openlabel.json")           # DocumentError lists every problem
    write_document("out.openlabel.json", write_openlabel(scene))

The document vocabulary is described in ``docs/scene-format.md``. Implementation,
one module of this package each: ``load`` (files, JSON, VCD 4.3 → OpenLABEL, provenance),
``read`` (the reader that ties the sections together: ``metadata``, ``cameras`` with ``poses``
and ``intrinsics``, ``objects``, ``relations``), ``write`` (the normal form), ``checks`` (the
official schema), ``values`` (value readers and pose encodings), ``annotations`` (a run's labels
into the document), ``carry`` (content SceneSpec does not model), ``imaging`` (world and sensor
keys).
"""

from usdscene.converters.openlabel.checks import (
    SCHEMA_ENV,
    default_schema_path,
    packaged_schema_path,
    schema_path_from_env,
    schema_problems,
)
from usdscene.converters.openlabel.intrinsics import EQUISOLID_KB_COEFFS
from usdscene.converters.openlabel.load import SCHEMA_VERSION, load_document, load_with_provenance
from usdscene.converters.openlabel.poses import friendly_camera_rotation
from usdscene.converters.openlabel.read import read_loaded, read_openlabel
from usdscene.converters.openlabel.write import write_document, write_openlabel

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
