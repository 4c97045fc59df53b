"""Geometry of a glint: a rough coating's microfacet lobe between a light and the lens.

Used by the laminate candidate (:mod:`simgap.analysis.candidates._gloss`): the Beckmann distribution
of Mitsuba's ``roughplastic``, per tag the half-angle between the directions to the lens and to a
light beside it, and the coating's Fresnel reflectance towards the lens (its veil).
"""

from __future__ import annotations

import numpy as np

#: Smallest ``cos(theta_o)`` of the glint's ``1 / cos(theta_o)`` (a grazing view, 87 deg).
MIN_COS = 0.05
#: Index of refraction of the laminate (PET / acrylic film; Fresnel 4 % at normal incidence).
LAMINATE_IOR = 1.49


def fresnel_veil(cos_o: np.ndarray, ior: float = LAMINATE_IOR) -> np.ndarray:
    """The coating's unpolarised Fresnel reflectance at view angle ``theta_o``, over its normal one.

    A laminate mirrors its surroundings (the room's ambient light) into the lens with the
    dielectric Fresnel reflectance of its surface (Born & Wolf, *Principles of Optics*, 1.5.2),
    a veil over ink and paper alike that grows towards grazing views: 1 facing the lens, 1.26 at
    45 deg, 2.26 at 60 deg, 6.49 at 75 deg for ``ior`` 1.49. A rough coating spreads it
    without changing its mean, the shape fitted here (dimensionless, >= 1).
    """
    c = np.clip(np.asarray(cos_o, float), 1e-6, 1.0)
    sin_t = np.sqrt(1.0 - c**2) / ior
    cos_t = np.sqrt(1.0 - sin_t**2)
    r_s = ((c - ior * cos_t) / (c + ior * cos_t)) ** 2
    r_p = ((cos_t - ior * c) / (cos_t + ior * c)) ** 2
    normal = ((ior - 1.0) / (ior + 1.0)) ** 2
    return 0.5 * (r_s + r_p) / normal


def beckmann(cos_h: np.ndarray, alpha: float) -> np.ndarray:
    """Beckmann normal distribution ``D`` at ``cos(theta_h)`` (sr^-1).

    ``exp(-tan^2 / alpha^2) / (pi alpha^2 cos^4)``: the distribution of Mitsuba's
    ``roughplastic``, the laminate's BSDF (its default; the scene does not change it).
    """
    c2 = np.clip(cos_h, 1e-6, 1.0) ** 2
    tan2 = (1.0 - c2) / c2
    return np.exp(-tan2 / alpha**2) / (np.pi * alpha**2 * c2**2)


def lobe_geometry(
    eye_from_tag: np.ndarray, offset_x_m: float, offset_z_m: float = 0.0
) -> tuple[np.ndarray, ...]:
    """``cos(theta_h)``, ``cos(theta_o)``, ``cos(theta_l)`` and the distance to the light (m).

    ``eye_from_tag`` (N, 4, 4): each tag's pose in the eyepoint frame (its z column the normal);
    the light sits ``offset_x_m`` to the right of the lens and ``offset_z_m`` above it.
    """
    position, normal = eye_from_tag[:, :3, 3], eye_from_tag[:, :3, 2]
    to_eye = -position / np.linalg.norm(position, axis=1, keepdims=True)
    to_light = np.array([offset_x_m, 0.0, offset_z_m]) - position
    distance = np.linalg.norm(to_light, axis=1)
    half = to_eye + to_light / distance[:, None]
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    cos_h = np.abs(np.sum(normal * half, axis=1))
    cos_o = np.abs(np.sum(normal * to_eye, axis=1))
    cos_l = np.clip(np.sum(normal * to_light, axis=1) / distance, 0.0, 1.0)
    return cos_h, cos_o, cos_l, distance
