"""A Mitsuba sensor that follows OpenCV's camera models exactly.

Mitsuba's built-in ``perspective`` sensor cannot do ``fx != fy`` nor lens distortion, and moving its
crop window recompiles the render kernel. :class:`OpenCVCamera` generates, for every film sample,
the ray whose OpenCV projection (``cv2.projectPoints``, or ``cv2.fisheye.projectPoints`` for the
``equidistant`` model; same K and coefficients, :mod:`simgap.core.lens`) lands on that sample.
All its parameters are opaque Dr.Jit variables, so changing the pose, the intrinsics or the crop
window between renders reuses the compiled kernel.

Nothing happens at import: :func:`register_sensor` defines the class (it subclasses ``mi.Sensor``,
so it needs the variant set) and registers it as :data:`PLUGIN_NAME`; the renderer's one set-up
function, :func:`simgap.render.backend.mitsuba`, calls it.

Parameters
----------
film : hdrfilm
    Its size is the crop size (px); the crop's top-left pixel in the full image is ``crop_offset``.

Example
-------
>>> mi = simgap.render.backend.mitsuba()   # sets the variant and calls register_sensor(mi)
>>> cam = scene.sensors()[0]
>>> cam.set_intrinsics(fx=1386, fy=1386, cx=959.5, cy=539.5, distortion=(0, 0, 0, 0, 0),
...                    model="plumb_bob")
>>> cam.set_pose(rail_from_cv)          # 4x4, OpenCV camera axes in the scene frame
>>> cam.set_crop_offset(800, 400)       # px
"""

from __future__ import annotations

from types import ModuleType

import numpy as np

from simgap.core import lens

PLUGIN_NAME = "opencv_camera"
#: Fixed-point iterations used to invert the pinhole family's distortion per ray; 20 reach < 1e-6
#: px for D435-sized coefficients (checked against cv2.projectPoints in tests/test_render.py).
UNDISTORT_ITERATIONS = 20
#: Newton iterations inverting the fisheye's ``theta_d(theta)`` per ray (tests/test_render.py).
FISHEYE_ITERATIONS = 10
#: Coefficients the sensor holds: the pinhole family's 14 (shorter models padded with zeros).
_PINHOLE_COEFFS = 14

_REGISTERED: set[str] = set()


def register_sensor(mi: ModuleType) -> None:
    """Define :class:`OpenCVCamera` for ``mi``'s variant and register it as :data:`PLUGIN_NAME`.

    Idempotent per variant. Called by :func:`simgap.render.backend.mitsuba` once the variant is
    set; nothing registers at import.

    Parameters
    ----------
    mi : module
        The ``mitsuba`` module with its variant set.
    """
    variant = mi.variant()
    if variant in _REGISTERED:
        return
    cls = _sensor_class(mi)
    mi.register_sensor(PLUGIN_NAME, lambda props: cls(props))
    _REGISTERED.add(variant)


def _sensor_class(mi: ModuleType) -> type:
    """The sensor class, built on ``mi.Sensor`` of the active variant."""
    import drjit as dr

    def _opaque(values) -> list:
        return [dr.opaque(mi.Float, float(v)) for v in values]

    class OpenCVCamera(mi.Sensor):
        """OpenCV camera-model sensor with a movable crop window (see module docstring)."""

        def __init__(self, props: mi.Properties) -> None:
            super().__init__(props)
            self.set_intrinsics(1000.0, 1000.0, 0.0, 0.0, (0.0,) * 5, "plumb_bob")
            self.set_pose(np.eye(4))
            self.set_crop_offset(0, 0)
            self.set_lens(0.0, 1.0)

        def set_intrinsics(
            self, fx: float, fy: float, cx: float, cy: float, distortion, model: str
        ) -> None:
            """Set focal lengths and principal point (px) and ``model``'s coefficients.

            ``model`` and ``distortion`` as in :class:`simgap.core.rig.CameraModel`.
            """
            coeffs = np.asarray(distortion, float)
            self._k = _opaque((fx, fy, cx, cy))
            self._fisheye = lens.is_fisheye(model)
            self._has_distortion = bool(np.any(coeffs != 0.0))
            if self._fisheye:
                self._dist = _opaque(coeffs)
                return
            padded = np.zeros(_PINHOLE_COEFFS)
            padded[: coeffs.size] = coeffs
            self._dist = _opaque(padded)
            self._tilted = bool(np.any(padded[12:] != 0.0))
            if self._tilted:
                self._tilt_inverse = _opaque(np.linalg.inv(lens.tilt_matrix(*padded[12:])).ravel())

        def set_pose(self, scene_from_cv: np.ndarray) -> None:
            """Set the camera pose: OpenCV camera frame in the scene frame (4x4, m)."""
            m = np.asarray(scene_from_cv, float)
            self._m = [_opaque(m[i]) for i in range(3)]

        def set_crop_offset(self, x0: int, y0: int) -> None:
            """Set the full-image pixel of the film's top-left corner (px)."""
            self._offset = _opaque((x0, y0))

        def set_lens(self, aperture_radius: float, focus_distance: float) -> None:
            """Thin lens: aperture radius (m; 0 = pinhole) and in-focus distance along z (m)."""
            self._thin_lens = aperture_radius > 0.0
            self._lens = _opaque((aperture_radius, focus_distance))

        def _undistort(self, xd, yd):
            """Normalised coordinates whose pinhole-family distortion is ``(xd, yd)``.

            The sensor tilt undone exactly, then the radial, tangential and thin-prism terms by
            fixed-point iteration (:mod:`simgap.core.lens` has the forward model).
            """
            if self._tilted:
                t = self._tilt_inverse
                w = t[6] * xd + t[7] * yd + t[8]
                xd, yd = (t[0] * xd + t[1] * yd + t[2]) / w, (t[3] * xd + t[4] * yd + t[5]) / w
            k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = self._dist[:12]
            x, y = xd, yd
            for _ in range(UNDISTORT_ITERATIONS):
                r2 = x * x + y * y
                radial = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (
                    1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
                )
                dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) + r2 * (s1 + r2 * s2)
                dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y + r2 * (s3 + r2 * s4)
                x = (xd - dx) / radial
                y = (yd - dy) / radial
            return x, y

        def _fisheye_direction(self, xd, yd):
            """Unit direction (x, y, z) whose fisheye projection is ``(xd, yd)``.

            ``theta`` from ``theta_d`` by Newton's method, then the ray at ``theta`` from the
            axis (valid beyond 90 deg, where the pinhole's ``(x, y, 1)`` is not).
            """
            k1, k2, k3, k4 = self._dist
            theta_d = dr.sqrt(xd * xd + yd * yd)
            theta = mi.Float(theta_d)
            for _ in range(FISHEYE_ITERATIONS):
                t2 = theta * theta
                f = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - theta_d
                df = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))
                theta = theta - f / df
            scale = dr.select(theta_d > 1e-12, dr.sin(theta) / theta_d, 1.0)
            return xd * scale, yd * scale, dr.cos(theta)

        def sample_ray(self, time, sample1, sample2, sample3, active=True):
            """Return the ray through film position ``sample2`` (in [0, 1]^2 of the crop)."""
            size = mi.ScalarVector2f(self.film().crop_size())
            u = self._offset[0] + sample2.x * size.x - 0.5
            v = self._offset[1] + sample2.y * size.y - 0.5
            return self.ray_through(u, v, sample3, time), mi.Spectrum(1.0)

        def ray_through(self, u, v, aperture_sample, time=0.0) -> mi.Ray3f:
            """The ray whose OpenCV projection is full-image pixel ``(u, v)``.

            Parameters
            ----------
            u, v : mi.Float
                Full-image pixel coordinates (px; OpenCV: pixel centres at integers).
            aperture_sample : mi.Point2f
                Uniform sample on [0, 1]^2 for the thin lens (unused by a pinhole).
            time : float or mi.Float
                Ray time (s; the fixture does not move during an exposure).
            """
            fx, fy, cx, cy = self._k
            x, y = (u - cx) / fx, (v - cy) / fy
            z = mi.Float(1.0)
            if self._fisheye:
                x, y, z = self._fisheye_direction(x, y)
            elif self._has_distortion:
                x, y = self._undistort(x, y)
            ox = oy = mi.Float(0.0)
            dx, dy, dz = x, y, z
            if self._thin_lens:
                # chief ray through the lens centre is the pinhole ray: blur is centred on it
                radius, focus = self._lens
                disk = mi.warp.square_to_uniform_disk_concentric(aperture_sample) * radius
                ox, oy = disk.x, disk.y
                dx, dy, dz = x / z * focus - ox, y / z * focus - oy, focus
            m = self._m
            d = mi.Vector3f(
                m[0][0] * dx + m[0][1] * dy + m[0][2] * dz,
                m[1][0] * dx + m[1][1] * dy + m[1][2] * dz,
                m[2][0] * dx + m[2][1] * dy + m[2][2] * dz,
            )
            origin = mi.Point3f(
                m[0][0] * ox + m[0][1] * oy + m[0][3],
                m[1][0] * ox + m[1][1] * oy + m[1][3],
                m[2][0] * ox + m[2][1] * oy + m[2][3],
            )
            return mi.Ray3f(origin, dr.normalize(d), time, [])

        def sample_ray_differential(self, time, sample1, sample2, sample3, active=True):
            """Ray without differentials (textures use nearest filtering)."""
            ray, weight = self.sample_ray(time, sample1, sample2, sample3, active)
            return mi.RayDifferential3f(ray), weight

        def traverse(self, callback) -> None:
            """Expose nothing to ``mi.traverse``: parameters are set by the ``set_*`` methods."""

        def to_string(self) -> str:
            """Short description."""
            return "OpenCVCamera[]"

    return OpenCVCamera
