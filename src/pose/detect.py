"""ArUco marker detection with recorded, configurable settings (OpenCV ``ArucoDetector``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np

from simgap.core.aruco import check_dictionary, predefined_dictionary
from simgap.core.config import require

REFINEMENTS = {
    "NONE": cv2.aruco.CORNER_REFINE_NONE,
    "SUBPIX": cv2.aruco.CORNER_REFINE_SUBPIX,
    "CONTOUR": cv2.aruco.CORNER_REFINE_CONTOUR,
    "APRILTAG": cv2.aruco.CORNER_REFINE_APRILTAG,
}
_DEFAULT_PARAMS = cv2.aruco.DetectorParameters()
#: Numeric ``cv2.aruco.DetectorParameters`` attributes and their types (int, float or bool).
PARAM_TYPES: dict[str, type] = {
    n: type(getattr(_DEFAULT_PARAMS, n))
    for n in dir(_DEFAULT_PARAMS)
    if not n.startswith("_") and type(getattr(_DEFAULT_PARAMS, n)) in (int, float, bool)
}
#: Parameters set through DetectorSettings' own fields (``extra`` may not override them).
_OWN_PARAMS = {
    "cornerRefinementMethod": "corner_refinement",
    "cornerRefinementWinSize": "subpix_window_px",
    "cornerRefinementMaxIterations": "subpix_max_iterations",
    "cornerRefinementMinAccuracy": "subpix_min_accuracy_px",
}
#: Parameters that may be negative (the adaptive threshold's constant); all others are >= 0.
_SIGNED_PARAMS = {"adaptiveThreshConstant"}


def _check_extra(extra: dict[str, float | bool]) -> None:
    """Names, types and ranges of ``DetectorSettings.extra`` (OpenCV's own checks included)."""
    for name, value in extra.items():
        require(
            name in PARAM_TYPES,
            f"extra.{name}: not a numeric cv2.aruco.DetectorParameters attribute; expected one of "
            f"{', '.join(sorted(set(PARAM_TYPES) - set(_OWN_PARAMS)))}",
        )
        require(
            name not in _OWN_PARAMS,
            f"extra.{name}: set by detector.{_OWN_PARAMS.get(name)}, not by extra",
        )
        kind = PARAM_TYPES[name]
        if kind is bool:
            require(value in (0, 1), f"extra.{name}: expected true/false (or 1/0), got {value!r}")
            continue
        require(
            not isinstance(value, bool) and math.isfinite(value),
            f"extra.{name}: expected a finite number, got {value!r}",
        )
        require(
            kind is float or float(value).is_integer(),
            f"extra.{name}: expected an integer (OpenCV's type is int), got {value!r}",
        )
        require(
            kind is float or abs(value) < 2**31,
            f"extra.{name}: expected a 32-bit integer, got {value!r}",
        )
        require(
            name in _SIGNED_PARAMS or value >= 0,
            f"extra.{name}: expected a value >= 0, got {value!r}",
        )


def _check_with_opencv(settings: DetectorSettings) -> None:
    """Run the detector once on a synthetic marker so OpenCV's own parameter checks run now."""
    dictionary = predefined_dictionary(settings.dictionary)
    side = 8 * (dictionary.markerSize + 2)
    img = np.full((4 * side, 4 * side), 255, np.uint8)
    img[side : 2 * side, side : 2 * side] = cv2.aruco.generateImageMarker(dictionary, 0, side)
    try:
        Detector(settings).detect(img)
    except cv2.error as exc:
        lines = [s.strip() for s in str(exc).splitlines() if s.strip()]
        reason = lines[-1] if lines else str(exc)
        raise ValueError(f"extra: OpenCV refuses these detector parameters ({reason})") from None


@dataclass(frozen=True)
class DetectorSettings:
    """Settings of OpenCV's ArUco detector.

    Attributes
    ----------
    dictionary : str
        ``cv2.aruco`` predefined dictionary name.
    corner_refinement : {"NONE", "SUBPIX", "CONTOUR", "APRILTAG"}
        Corner refinement method.
    subpix_window_px : int
        Half-size of the SUBPIX refinement window (px).
    subpix_max_iterations : int
        Maximum SUBPIX iterations.
    subpix_min_accuracy_px : float
        SUBPIX stopping accuracy (px).
    extra : dict of str to float or bool
        Any other numeric ``cv2.aruco.DetectorParameters`` attribute, by its OpenCV name: finite,
        integral where OpenCV's type is int, ``>= 0`` (except ``adaptiveThreshConstant``), and
        accepted by OpenCV's own checks (a detection is run on a synthetic marker to make sure).
    """

    dictionary: str = "DICT_ARUCO_MIP_36H12"
    corner_refinement: Literal["NONE", "SUBPIX", "CONTOUR", "APRILTAG"] = "SUBPIX"
    subpix_window_px: int = 5
    subpix_max_iterations: int = 100
    subpix_min_accuracy_px: float = 0.01
    extra: dict[str, float | bool] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_dictionary(self.dictionary)
        require(self.subpix_window_px >= 1, "subpix_window_px: expected an integer >= 1")
        require(self.subpix_max_iterations >= 1, "subpix_max_iterations: expected an integer >= 1")
        require(
            math.isfinite(self.subpix_min_accuracy_px) and self.subpix_min_accuracy_px > 0,
            "subpix_min_accuracy_px: expected a positive accuracy (px)",
        )
        if self.extra:
            _check_extra(self.extra)
            _check_with_opencv(self)


class Detector:
    """An ``ArucoDetector`` built from :class:`DetectorSettings`."""

    def __init__(self, settings: DetectorSettings) -> None:
        self.settings = settings
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = REFINEMENTS[settings.corner_refinement]
        params.cornerRefinementWinSize = settings.subpix_window_px
        params.cornerRefinementMaxIterations = settings.subpix_max_iterations
        params.cornerRefinementMinAccuracy = settings.subpix_min_accuracy_px
        for name, value in settings.extra.items():
            setattr(params, name, type(getattr(params, name))(value))
        self._params = params
        self._dictionary = predefined_dictionary(settings.dictionary)
        self._detector = cv2.aruco.ArucoDetector(self._dictionary, params)

    @property
    def window_pad_px(self) -> int | None:
        """How far the detector looks beyond the frame's non-flat pixels (px), or None.

        A window of a frame that holds every non-flat pixel plus this much of the flat fill
        around them detects exactly what the whole frame does (:meth:`detect_with_rejected`
        with ``origin`` and ``frame_size``): the adaptive threshold of a flat area is empty, so
        no contour starts further out than half its largest window, and candidates closer than
        ``minDistanceToBorder`` to the window's edge could not exist there. None where the
        detector looks at the whole image (ArUco 3's pyramid, AprilTag refinement): only the
        whole frame is exact then.
        """
        p = self._params
        if p.useAruco3Detection or p.cornerRefinementMethod == cv2.aruco.CORNER_REFINE_APRILTAG:
            return None
        threshold_reach = p.adaptiveThreshWinSizeMax // 2 + p.minDistanceToBorder
        return threshold_reach + p.cornerRefinementWinSize + 4

    def detect(self, gray: np.ndarray) -> dict[int, np.ndarray]:
        """Detect markers in an 8-bit grey frame.

        Returns
        -------
        dict
            Tag id -> corners (4, 2) in px, ordered TL, TR, BR, BL. A tag id seen twice keeps
            the larger detection.
        """
        return self.detect_with_rejected(gray)[0]

    def detect_with_rejected(
        self,
        gray: np.ndarray,
        origin: tuple[int, int] = (0, 0),
        frame_size: tuple[int, int] | None = None,
    ) -> tuple[dict[int, np.ndarray], list[np.ndarray]]:
        """Detected markers (as :meth:`detect`) and the rejected candidate quads (4, 2) in px.

        Parameters
        ----------
        gray : ndarray of uint8 (H, W)
            The grey frame, or a window of it (see :attr:`window_pad_px`).
        origin : tuple of int
            Where the window's top-left pixel sits in the frame (x0, y0 px); corners are
            returned in frame pixels.
        frame_size : tuple of int, optional
            The frame's (W, H) in px when ``gray`` is a window of it: the marker perimeter
            limits, which OpenCV sets relative to the image's larger side, are those of the
            frame.
        """
        detector = self._detector
        if frame_size is not None and max(frame_size) != max(gray.shape):
            detector = cv2.aruco.ArucoDetector(
                self._dictionary, self._scaled_params(max(frame_size), max(gray.shape))
            )
        corners, ids, rejected = detector.detectMarkers(gray)
        shift = np.asarray(origin, np.float64)
        rejected_quads = [np.asarray(q, np.float64).reshape(4, 2) + shift for q in rejected]
        found: dict[int, np.ndarray] = {}
        if ids is None:
            return found, rejected_quads
        for c, i in zip(corners, ids.ravel(), strict=True):
            c = c.reshape(4, 2).astype(np.float64)
            if int(i) not in found or cv2.contourArea(c.astype(np.float32)) > cv2.contourArea(
                found[int(i)].astype(np.float32)
            ):
                found[int(i)] = c
        return {i: c + shift for i, c in found.items()}, rejected_quads

    def _scaled_params(self, frame_side: int, window_side: int) -> cv2.aruco.DetectorParameters:
        """The detector's parameters with the frame's perimeter limits on a window's side (px).

        OpenCV truncates ``rate * side`` to whole pixels; the rates given here truncate to the
        same whole pixels on the window as the original rates on the frame.
        """
        params = cv2.aruco.DetectorParameters()
        for name in PARAM_TYPES:
            setattr(params, name, getattr(self._params, name))
        for name in ("minMarkerPerimeterRate", "maxMarkerPerimeterRate"):
            pixels = math.floor(getattr(self._params, name) * frame_side)
            setattr(params, name, (pixels + 0.5) / window_side)
        return params
