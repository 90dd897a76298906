"""The Blender process: the only package of usdscene that imports ``bpy``, and only inside a
worker process (:mod:`usdscene.render.worker` is its entry point).

- :mod:`.process`: the worker's side of the process boundary (events on stdout, importing
  ``bpy``, memory, dying with the parent);
- :mod:`.cycles`: the render engine, the GPU and Cycles' settings;
- :mod:`.session`: :class:`~.session.Session`, one imported stage shard and one render camera,
  rendering (frame, camera) pairs;
- :mod:`.camera`: a lens as Blender camera data;
- :mod:`.world`: the document's world as Blender nodes, and baking it into an image;
- :mod:`.outputs`: decoding Blender's EXR, encoding and writing the PNGs;
- :mod:`.blend`: Blender projects: writing one of a stage, exporting and inspecting one.
"""
