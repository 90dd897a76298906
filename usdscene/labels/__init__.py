"""Labels of one image: lens projection, the amodal (unoccluded) projection of objects, boxes,
polygons and visibility from instance masks, pixel density and detail levels, and what one
object looks like across cameras. Pure maths on arrays (numpy, OpenCV, numba); no pxr, no bpy."""
