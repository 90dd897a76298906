"""Dataset exports written from a run's annotations: training formats (COCO, YOLO, ROI crops)
and tracking formats (MOT, multi-view ground plane, tracks). One module per format."""
