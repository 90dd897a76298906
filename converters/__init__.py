"""Format converters around the SceneSpec hub: OpenLABEL/VCD ↔ SceneSpec, USD stage ↔
SceneSpec, and dataset exporters (COCO, YOLO, ROI crops). Every format converts to and from
``usdscene.document.model.SceneSpec``, never directly to another format."""
