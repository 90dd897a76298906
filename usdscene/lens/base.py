"""The lens interface and its registry (see :mod:`usdscene.lens`)."""

from __future__ import annotations

import functools
import math

import numpy as np


class Lens:
    """One projection model. Subclasses set the class attributes and implement :meth:`project`
    and :meth:`unproject`; Blender-native models implement :meth:`blender_camera`.

    Attributes:
        name: the model's name (``Intrinsics.lens``, a :class:`usdscene.document.model.LensModel` value).
        pinhole: a central projection onto a plane (``u = fx·x/z + cx`` before distortion);
            valid in front of the camera only.
        orthographic: a parallel projection (``fx`` in pixels per metre).
        radial: maps the angle ``θ`` off the axis to an image radius; has an image circle
            (``Intrinsics.fov_deg``).
        straight: straight lines stay straight in the image (an undistorted pinhole or a
            parallel projection): a triangle projects to a triangle.
        native: Blender renders the model directly (else through a native lens and a remap).
        centred: natively rendered only with the principal point at the image centre (Cycles'
            panoramic cameras ignore lens shift).
        polynomial: a radial lens whose ``θd(θ)`` is a polynomial (rendered through a native
            fisheye, or a perspective view when it is narrow).
        default_half_fov_rad: the widest angle off the axis without a ``fov_deg``.
        calibration_family: the model an OpenLABEL calibration of this lens reads back as
            when no model is named (``perspective`` for both pinholes, ``opencv_fisheye`` for
            the Blender fisheyes, written as that); models of one family may name each other's
            calibration.
        brown_conrady: its coefficients are OpenCV's ``k1 k2 p1 p2 [k3 [k4 k5 k6]]``.
        distortion_lengths: how many coefficients its friendly ``distortion`` may hold
            (empty: the model has none); ``distortion_what`` says what they are.
        default_distortion: its coefficients when the friendly form gives none.
        fov_spans_width: the friendly ``fov_deg`` spans the sensor width (``r = f·θ`` as
            Blender's equidistant fisheye maps it), so it sets the focal length.
        catalog: a planner catalog lens may have this model (focal length, sensor width and
            image circle say all of it).
    """

    name = ""
    pinhole = False
    orthographic = False
    radial = False
    straight = False
    native = False
    centred = False
    polynomial = False
    default_half_fov_rad = math.pi
    calibration_family = ""
    brown_conrady = False
    distortion_lengths: tuple[int, ...] = ()
    distortion_what = "numbers"
    default_distortion: tuple[float, ...] = ()
    fov_spans_width = False
    catalog = True

    def from_calibration(self, coefficients: tuple[float, ...], where: str, problems) -> tuple[float, ...] | None:
        """This lens's coefficients from those of the calibration of its family that a document
        gives with this model named; None (the problem added to ``problems`` at ``where``) when
        they do not describe this model."""
        return coefficients

    def project(self, intrinsics, x: np.ndarray, y: np.ndarray, z: np.ndarray):
        """Camera-frame coordinates (N,) each (OpenCV axes, metres) → ``(xn, yn, valid, theta)``:
        normalised image coordinates (pixels are ``fx·xn + cx``, ``fy·yn + cy``), whether each
        point is imaged, and for radial models the angle off the axis (radians), else None."""
        raise NotImplementedError

    def unproject(self, intrinsics, xd: np.ndarray, yd: np.ndarray, iterations: int):
        """Normalised image coordinates (N,) each → ``(rays (N, 3), valid (N,))``: unit directions
        in the camera frame and whether the position has a ray (see
        :func:`usdscene.labels.projection.pixel_rays`)."""
        raise NotImplementedError

    def half_fov_rad(self, intrinsics) -> float:
        """Largest angle off the axis that the lens images: ``fov_deg / 2``, else the model's default."""
        if intrinsics.fov_deg is not None:
            return math.radians(intrinsics.fov_deg) / 2.0
        return self.default_half_fov_rad

    def openlabel_calibration(self, intrinsics, size: dict, where: str, problems) -> dict:
        """The OpenLABEL ``stream_properties`` calibration that reproduces the lens
        (``intrinsics_pinhole``, ``intrinsics_fisheye`` or ``intrinsics_custom``), ``size`` its
        ``width_px`` / ``height_px``; a bad coefficient count is added to ``problems`` (a
        :class:`usdscene.errors.ProblemCollector`) at ``where``."""
        raise NotImplementedError

    def opencv_distortion(self, intrinsics):
        """``(OpenCV model, D)``: ``"pinhole"`` (``cv2.projectPoints``) or ``"fisheye"``
        (``cv2.fisheye``) and the distortion coefficients that reproduce the lens with the
        camera matrix K; None when OpenCV has no model for it."""
        return None

    def opencv_fit_error_px(self, intrinsics) -> float:
        """Largest image distance (pixels) between the lens and its :meth:`opencv_distortion`
        export over the lens's field of view: 0.0 where the export is exact (or there is none)."""
        return 0.0

    def blender_camera(self, intrinsics) -> dict:
        """Blender camera data settings (attribute → value, in the order they are set) beyond the
        sensor and lens shift, for a native lens.

        Raises:
            ValueError: the model is not native to Blender.
        """
        raise ValueError(f"lens {self.name!r} is not native to Blender")


LENSES: dict[str, Lens] = {}
"""Model name → lens."""


def register(lens: Lens) -> Lens:
    """Add ``lens`` to :data:`LENSES` under its name (once); returns it."""
    if not lens.name:
        raise ValueError(f"{type(lens).__name__} has no name")
    if lens.name in LENSES:
        raise ValueError(f"lens {lens.name!r} is registered already")
    LENSES[lens.name] = lens
    return lens


def lens_for(model) -> Lens:
    """The lens of a model name, a :class:`~usdscene.document.model.LensModel` or an object with
    a ``lens`` (an :class:`~usdscene.document.model.Intrinsics`).

    Raises:
        KeyError: no lens of that name is registered.
    """
    name = getattr(model, "lens", model)
    return LENSES[getattr(name, "value", name)]


@functools.lru_cache(maxsize=32)
def valid_pixels(intrinsics) -> np.ndarray:
    """(H, W) bool, read-only: the pixels of an image of ``intrinsics`` (an
    :class:`~usdscene.document.model.Intrinsics`) that the lens images, i.e. that have a viewing
    ray: all of them for a pinhole, those inside the image circle for a fisheye. The renderer
    blacks out the rest and image statistics leave them out. Cached per lens (it is the same for
    every image of a camera)."""
    vs, us = np.mgrid[0:intrinsics.height_px, 0:intrinsics.width_px]
    xd = (us.ravel().astype(np.float64) - intrinsics.cx_px) / intrinsics.fx_px
    yd = (vs.ravel().astype(np.float64) - intrinsics.cy_px) / intrinsics.fy_px
    _, valid = lens_for(intrinsics).unproject(intrinsics, xd, yd, 40)
    out = np.asarray(valid, dtype=bool).reshape(intrinsics.height_px, intrinsics.width_px)
    out.setflags(write=False)
    return out
