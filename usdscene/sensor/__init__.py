"""The camera after the light: what a surveillance camera's optics, sensor, processing and
encoder make of a rendered image. Pure package (numpy + OpenCV; no bpy, no pxr).

* :mod:`usdscene.sensor.exposure`: metering and auto exposure on the linear render;
* :mod:`usdscene.sensor.tone`: the tone curve (sRGB, or wide dynamic range) to 8 bits;
* :mod:`usdscene.sensor.optics`: lens blur, unsharp-mask edge enhancement, 4:2:0 chroma;
* :mod:`usdscene.sensor.pipeline`: the whole chain in a camera's order (:func:`process_image`),
  the noise and compression, and what the annotations record.

Masks and labels never pass through it.
"""
