"""What a variant is made of, stage by stage: the state effects transform."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from simgap.core.rig import NOMINAL, CameraModel, FixtureErrors
from simgap.pose.tags import Estimation
from simgap.scene.spec import SceneSpec, default_scene_spec


@dataclass(frozen=True)
class RenderQuality:
    """Renderer quality: samples per pixel, sampler, path depth, mode.

    ``mode``: ``path`` (every pixel the mean of its path-traced samples) or ``converged``
    (stickers demodulated by their albedo, :mod:`simgap.render.converged`).
    """

    spp: int = 16
    sampler: str = "multijitter"
    max_depth: int = 3
    mode: str = "path"


@dataclass(frozen=True)
class SceneState:
    """Everything the render depends on (besides p and theta).

    Attributes
    ----------
    spec : SceneSpec
        The scene description (:mod:`simgap.scene`): materials, tag print, lights, objects,
        integrator; scene-stage effects replace parts of it.
    camera : CameraModel
        The true camera (intrinsics px, distortion model and coefficients).
    errors : FixtureErrors
        The true fixture's differences from CAD.
    tag_scale : float
        Printed sticker size relative to nominal.
    aperture_radius_m, focus_distance_m : float
        Thin lens (m); radius 0 is a pinhole.
    quality : RenderQuality
        Samples per pixel, sampler and path depth.
    render_seed : int
        Base seed of the renderer's sampler.
    """

    spec: SceneSpec = field(default_factory=default_scene_spec)
    camera: CameraModel = field(default_factory=CameraModel)
    errors: FixtureErrors = NOMINAL
    tag_scale: float = 1.0
    aperture_radius_m: float = 0.0
    focus_distance_m: float = 1.0
    quality: RenderQuality = field(default_factory=RenderQuality)
    render_seed: int = 0


@dataclass(frozen=True)
class ImageState:
    """The camera pipeline: linear-domain operations, encoding, post-quantisation operations.

    Attributes
    ----------
    ops : tuple
        ``(effect name, params)`` of image effects, applied in their class ``order``.
    encoding : str
        ``"srgb"`` or ``"gamma"`` (with ``gamma``) or ``"linear"``.
    gamma : float
        Exponent of the ``gamma`` encoding (encoded = linear ** (1 / gamma)).
    exposure : float
        Linear gain before encoding.
    """

    ops: tuple[tuple[str, Any], ...] = ()
    encoding: str = "srgb"
    gamma: float = 2.2
    exposure: float = 1.0

    @property
    def stochastic(self) -> bool:
        """Whether the pipeline draws random numbers (then repeats differ)."""
        # the registry is read when asked, not imported with this module: simgap.effects.base
        # names VariantState in its annotations, so state stays below it
        from simgap.effects.base import EFFECTS

        return any(EFFECTS[name].stochastic for name, _ in self.ops)


@dataclass(frozen=True)
class VariantState:
    """One variant: scene, image and estimation stages (the ground truth is the nominal rig)."""

    scene: SceneState = field(default_factory=SceneState)
    image: ImageState = field(default_factory=ImageState)
    estimation: Estimation = field(default_factory=Estimation)
