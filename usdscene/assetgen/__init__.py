"""The procedural asset library generator (imports pxr).

- :mod:`usdscene.assetgen.mesh`: pure-numpy mesh builders (rounded boxes, capsules, lathes, ...).
- :mod:`usdscene.assetgen.usd_write`: stage metadata, meshes, materials, variants, atomic .usda.
- :mod:`usdscene.assetgen.cabin`: the ``aircraft_cabin`` environment and its places.
- :mod:`usdscene.assetgen.objects`: the 22 object classes and their variants.
- :mod:`usdscene.assetgen.body_model`, :mod:`usdscene.assetgen.people`: the ``person`` and seated
  ``passenger`` classes, baked from MakeHuman/MPFB2 body data (``python assets/generate.py --people``).
- :mod:`usdscene.assetgen.library`: ``build_library(folder)`` writes everything + catalog.json.

Rebuild the shipped library with ``usdscene assets build`` (or ``python assets/generate.py``);
the output is byte-identical for the same code.
"""
