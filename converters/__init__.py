"""Format converters around the SceneSpec hub, one subpackage per kind of work:

- ``openlabel/``: OpenLABEL 1.0.0 / VCD 4.3 documents ↔ SceneSpec (read, write, schema checks);
- ``stage/``: a USD stage ↔ SceneSpec (the reverse route from composed or DCC-edited stages);
- ``exports/``: the dataset formats written from a run's annotations (COCO, YOLO, ROI crops,
  MOT, multi-view, tracks).

Every format converts to and from ``usdscene.document.model.SceneSpec``, never directly to
another format."""
