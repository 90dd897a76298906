"""usdscene: OpenLABEL scene descriptions → layered USD stages → labeled multi-camera datasets.

The package root exposes the plain scene model only; composition (pxr), rendering (bpy) and
labels live in their own modules and are imported explicitly.
"""

__version__ = "0.1.0"

from usdscene.errors import UsdSceneError  # noqa: E402

__all__ = ["__version__", "UsdSceneError"]
