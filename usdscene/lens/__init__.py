"""Lens models: one class per model, looked up by name. Pure (numpy).

A lens class holds what usdscene knows about its model: the projection of camera-frame points
to normalised image coordinates and back (:meth:`Lens.project`, :meth:`Lens.unproject`), what
kind of projection it is (a pinhole, a parallel projection, an angle-to-radius fisheye), whether
Blender renders it directly and with which camera settings (:meth:`Lens.blender_camera`, plain
data). :mod:`usdscene.labels.projection` turns these into pixels, rays and remap grids.

Every model of :class:`usdscene.document.model.LensModel` is registered here; a lens of another
name is one :class:`Lens` subclass and one :func:`register` call (``tests/test_registries.py``
adds a toy lens that way).
"""

from __future__ import annotations

from usdscene.lens.base import LENSES, Lens, lens_for, register, valid_pixels
from usdscene.lens.fisheye import EquidistantFisheye, EquisolidFisheye, KannalaFisheye, OpenCVFisheye, RadialPolynomial
from usdscene.lens.pinhole import OpenCVPinhole, Orthographic, Perspective

for _lens in (Perspective(), Orthographic(), EquidistantFisheye(), EquisolidFisheye(), OpenCVPinhole(),
              OpenCVFisheye(), KannalaFisheye(), RadialPolynomial()):
    register(_lens)

__all__ = ["LENSES", "Lens", "lens_for", "register", "valid_pixels"]
