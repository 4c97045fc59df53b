"""Converged renders under the sun where the fixture's own shadow edge crosses a sticker.

The scene-stage effect ``sun`` (parallel rays, 1361 W m^-2) lights the fixture from behind the
camera, low enough that the camera body on the carriage shadows part of the facing sticker: a
hard edge across the paper and the print, which the converged render's smooth irradiance cannot
follow (:mod:`simgap.render.converged` path traces such a sticker again at 4x its samples). The
lab's key light is off (a point light of zero power: an area light's rectangle, even unlit,
would cast a shadow of its own) and the sky is a uniform environment of ``--skies`` radiance
(W m^-2 sr^-1; 0 is a black sky). The camera's exposure gain is ``pi / (E_sun + pi L_sky)``:
a white surface facing the sun and the whole sky reads 1, the lit paper (albedo 0.8) at most 0.8.

Per sky and :data:`CASES` entry (pin hole, turntable angle, sun azimuth and elevation), found
by ray casting the sticker's surface towards the sun in the loaded Mitsuba scene (``--search``
lists every candidate of a small grid with 20-80 % of the sticker shadowed), the whole pipeline
(region, render, 8-bit frame, ArUco, PnP) from an empty cache: path traced at ``--ref-spp``
(the reference) at render seeds 0 and 1, converged at ``--spp`` at ``--seeds`` render seeds and
path traced at each of ``--path-spp`` (seed 0). Printed per case: the shadowed share of the
sticker (ray cast) and the shadowed paper's level against the lit paper's (reference, linear);
per render its sticker treatment and, against reference seed 0 (a converged render also against
the two references' mean), the detected corners' distance (max and RMS over the four corners,
px), the pose difference (translation mm, rotation angle mrad), the sticker pixels' 8-bit
difference (DN, RMS and max) and their share more than :data:`FIREFLY_DN` above the
reference's (fireflies); reference seed 1 against seed 0 is the reference's own noise. The
issue's bars: corners within 0.05 px, pose within 0.1 mm and 1 mrad of the reference.
``--figure`` draws one case (converged frame, reference, their difference, the geometric shadow
boundary over each); ``--effects`` adds effects to every case (a JSON mapping).

Results: docs/results/shadow_edge.md.

Usage: ``python benchmarks/shadow_edge.py [--skies 0,200] [--ref-spp 4096] [--spp 4]
[--seeds 2] [--path-spp 16,256] [--figure docs/results/shadow_edge.png] [--figure-case
corner_p0] [--figure-sky 200] [--effects JSON] [--search]``
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage

from simgap.analysis.thresholds import FLIP_RAD
from simgap.core import transforms as tf
from simgap.core.rig import Rig, load_rig
from simgap.effects.scene import SOLAR_CONSTANT_W_M2, sun_direction
from simgap.pipeline.experiment import Experiment, load_experiment
from simgap.pipeline.experiment_settings import VariantSpec
from simgap.pipeline.sweep import experiment_pipelines
from simgap.pipeline.variant import VariantPipeline
from simgap.pose.tags import ConfigResult
from simgap.render.scene import FixtureScene, pose_transforms, projected_sticker_outlines
from simgap.scene.lights import BT709_LUMINANCE

REPO = Path(__file__).resolve().parents[1]
#: Shadow rays start this far off the sticker, along its normal (m): clear of the sticker's own
#: rectangle in float32 (about 3e-8 m at the fixture's 0.3 m), far below a pixel's footprint
#: (0.15 mm at 0.2 m).
RAY_OFFSET_M = 1e-5
#: Bisection steps of :func:`shadow_boundary`: the grid's step (0.3 mm) halved until it is far
#: below the float32 resolution of the rays' origins (about 3e-8 m).
BISECTIONS = 30
#: A sticker pixel this much brighter than the reference's is counted as a firefly (DN of the
#: 8-bit frame; 4.4x the RMS difference of two 1024-spp references under the black sky, 9x under
#: the sky of 200 W m^-2 sr^-1).
FIREFLY_DN = 20.0
#: The issue's bars: corners (px), translation (mm) and rotation (mrad) from the reference.
BARS = (0.05, 0.1, 1.0)


@dataclasses.dataclass(frozen=True)
class SunCase:
    """A configuration and a sun direction under which the fixture shadows part of a sticker.

    Attributes
    ----------
    name : str
        Variant name.
    p : int
        Carriage pin hole.
    theta_deg : float
        Turntable angle (deg).
    azimuth_deg, elevation_deg : float
        The sun's direction (deg; :class:`simgap.effects.scene.Sun`).
    tag : int
        The sticker the shadow edge crosses.
    """

    name: str
    p: int
    theta_deg: float
    azimuth_deg: float
    elevation_deg: float
    tag: int = 0

    @property
    def theta(self) -> float:
        """Turntable angle (rad)."""
        return float(np.radians(self.theta_deg))

    @property
    def direction(self) -> np.ndarray:
        """Unit vector towards the sun, rail frame (dimensionless)."""
        return sun_direction(self.azimuth_deg, self.elevation_deg)

    def sun(self) -> dict[str, float]:
        """The ``sun`` effect's parameters (deg): parallel rays, the hardest edge there is."""
        return {
            "azimuth_deg": self.azimuth_deg,
            "elevation_deg": self.elevation_deg,
            "angular_diameter_deg": 0.0,
        }


#: Found with ``--search`` (shadowed share of tag 0 by ray casting: 48, 41, 31 and 45 %). The
#: camera body's top edge across the middle of the marker; its bottom and side edges meeting in
#: a corner over the sticker's upper left, at three distances.
CASES = (
    SunCase("top_edge", 0, 0.0, 190.0, 8.0),
    SunCase("corner_p0", 0, 10.0, 185.0, 3.0),
    SunCase("corner_p3", 3, 340.0, 175.0, 2.0),
    SunCase("corner_p6", 6, 20.0, 185.0, 2.0),
)


def sun_experiment(
    cases: tuple[SunCase, ...],
    sky: float,
    base: str = "experiments/baseline.yaml",
    extra: dict[str, dict] | None = None,
) -> Experiment:
    """``base`` with the key light off, a sky of radiance ``sky`` and one variant a case.

    Parameters
    ----------
    cases : tuple of SunCase
        One variant each, named by the case, adding the ``sun`` effect.
    sky : float
        The ambient environment's radiance (W m^-2 sr^-1; 0: a black sky).
    base : str
        Experiment file, relative to the repository (its render settings are kept).
    extra : dict, optional
        More effects for every variant (effect name -> parameters).
    """
    exp = load_experiment(REPO / base)
    effects = {
        **exp.effects,
        "lighting": {"type": "point", "power": 0.0},
        "ambient": {"radiance": float(sky)},
        **(extra or {}),
    }
    exposure = np.pi / (SOLAR_CONSTANT_W_M2 + np.pi * sky)
    return dataclasses.replace(
        exp,
        name="shadow_edge",
        effects=effects,
        image=dataclasses.replace(exp.image, exposure=float(exposure)),
        variants=tuple(VariantSpec(c.name, {"sun": c.sun()}) for c in cases),
    )


def _sticker_frame(scene: FixtureScene, tag: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The posed scene's transforms (:func:`pose_transforms`) and the sticker's rail-frame one."""
    if scene.pose is None:
        raise RuntimeError("set_pose() must be called first")
    world = pose_transforms(scene.rig, *scene.pose, scene.errors, scene.tag_scale)
    return world[f"tag_{tag}"], world


#: Farthest a shadow ray looks for an occluder (m): past the fixture (under 2 m across), short of
#: the emitting disc that renders the sun (:data:`simgap.render.mitsuba_scene.DISTANT_DISC_M`).
FIXTURE_REACH_M = 100.0


def shadowed(scene: FixtureScene, tag: int, local: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Whether the fixture blocks the ray towards ``direction`` from points of a sticker.

    Parameters
    ----------
    scene : FixtureScene
        A posed scene (its loaded Mitsuba scene's ``ray_test``).
    tag : int
        The sticker.
    local : ndarray (N, 2)
        Points on the sticker in its ``[-1, 1]^2`` rectangle (x right, y up as printed).
    direction : ndarray (3,)
        Unit vector towards the light, rail frame.

    Returns
    -------
    ndarray of bool (N,)
        True where the ray meets the fixture (a sticker facing away counts as shadowed).
    """
    mi = scene.mi
    rail_from_sticker, _ = _sticker_frame(scene, tag)
    local = np.atleast_2d(local)
    points = tf.apply(rail_from_sticker, np.c_[local, np.zeros(len(local))])
    normal = rail_from_sticker[:3, 2] / np.linalg.norm(rail_from_sticker[:3, 2])
    if normal @ direction <= 0:
        return np.ones(len(local), bool)
    origin = (points + RAY_OFFSET_M * normal).astype(np.float32)
    # at least two lanes: a one-element array would become a literal of the kernel
    n = max(len(origin), 2)
    origin = np.resize(origin, (n, 3))
    towards = np.tile(np.asarray(direction, np.float32), (n, 1))
    # only the fixture occludes: rays stop well short of the sun's disc (a shape far away)
    maxt = mi.Float(np.full(n, FIXTURE_REACH_M, np.float32))
    ray = mi.Ray3f(mi.Ray3f(mi.Point3f(*origin.T), mi.Vector3f(*towards.T)), maxt)
    return np.asarray(scene.scene.ray_test(ray), bool)[: len(local)]


def sticker_grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres of an ``n x n`` grid over the sticker's ``[-1, 1]^2``: x and y (n, n)."""
    s = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    return np.meshgrid(s, s)


def shadowed_share(scene: FixtureScene, case: SunCase, n: int = 64) -> float:
    """Share of the sticker's area in the fixture's shadow (ray cast on an ``n x n`` grid)."""
    x, y = sticker_grid(n)
    return float(shadowed(scene, case.tag, np.c_[x.ravel(), y.ravel()], case.direction).mean())


def shadow_boundary(scene: FixtureScene, case: SunCase, n: int = 97) -> np.ndarray:
    """Points of the geometric shadow boundary on the sticker, in its ``[-1, 1]^2`` (M, 2).

    Between every two neighbouring points of an ``n x n`` grid (along x or y) of which one is
    shadowed and the other not, the boundary is bisected :data:`BISECTIONS` times along the
    line joining them: where the ray towards the sun from the sticker is first blocked.
    """
    x, y = sticker_grid(n)
    grid = np.stack([x, y], axis=-1)
    dark = shadowed(scene, case.tag, grid.reshape(-1, 2), case.direction).reshape(n, n)
    pairs = []
    for axis in (0, 1):
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        differ = dark[tuple(a)] != dark[tuple(b)]
        lit_first = ~dark[tuple(a)][differ]
        ga, gb = grid[tuple(a)][differ], grid[tuple(b)][differ]
        pairs.append((np.where(lit_first[:, None], ga, gb), np.where(lit_first[:, None], gb, ga)))
    lit = np.concatenate([p[0] for p in pairs])
    dark_end = np.concatenate([p[1] for p in pairs])
    for _ in range(BISECTIONS):
        mid = (lit + dark_end) / 2
        blocked = shadowed(scene, case.tag, mid, case.direction)
        dark_end = np.where(blocked[:, None], mid, dark_end)
        lit = np.where(blocked[:, None], lit, mid)
    return (lit + dark_end) / 2


def sticker_to_image(scene: FixtureScene, tag: int, local: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) (px, OpenCV) of sticker points in its ``[-1, 1]^2``, by the scene's camera."""
    rail_from_sticker, world = _sticker_frame(scene, tag)
    local = np.atleast_2d(local)
    rail = tf.apply(rail_from_sticker, np.c_[local, np.zeros(len(local))])
    return scene.camera_model.project(tf.apply(tf.invert(world["camera"]), rail))


def quiet_zone_points(
    scene: FixtureScene, case: SunCase, n: int = 121, clear: int = 6
) -> tuple[np.ndarray, np.ndarray]:
    """Points of the sticker's white quiet zone, lit and shadowed, away from every edge.

    Grid points (``n x n``) with ``max(|x|, |y|)`` in the inner 70 % of the quiet zone (no print
    or sticker edge within 15 % of its width) whose ``clear`` neighbours along each axis are in
    the same light. Returns the lit and the shadowed points (each (M, 2), sticker ``[-1, 1]^2``).
    """
    rig = scene.rig
    cells = rig.marker_cells() + 2 * rig.tags.quiet_zone_cells
    inner = 1.0 - 2.0 * rig.tags.quiet_zone_cells / cells  # where the marker's border begins
    x, y = sticker_grid(n)
    ring = np.maximum(np.abs(x), np.abs(y))
    width = 1.0 - inner
    paper = (ring > inner + 0.15 * width) & (ring < 1.0 - 0.15 * width)
    dark = shadowed(scene, case.tag, np.c_[x.ravel(), y.ravel()], case.direction).reshape(n, n)
    structure = np.ones((2 * clear + 1, 2 * clear + 1), bool)
    lit = paper & ndimage.binary_erosion(~dark, structure, border_value=1)
    shade = paper & ndimage.binary_erosion(dark, structure, border_value=1)
    return np.c_[x[lit], y[lit]], np.c_[x[shade], y[shade]]


def luminance(rgb: np.ndarray) -> np.ndarray:
    """BT.709 luminance of linear RGB (..., 3)."""
    return np.asarray(rgb, np.float64) @ np.asarray(BT709_LUMINANCE)


def paper_levels(
    scene: FixtureScene, case: SunCase, hdr: np.ndarray, offset: tuple[int, int]
) -> tuple[float, float]:
    """Median luminance of the lit and of the shadowed quiet-zone paper in a linear crop.

    ``hdr`` is the case's linear render (H, W, 3), its top-left pixel at ``offset`` (px) of the
    full image; NaN where the quiet zone has no such paper.
    """
    levels = []
    for points in quiet_zone_points(scene, case):
        if not len(points):
            levels.append(float("nan"))
            continue
        uv = np.round(sticker_to_image(scene, case.tag, points)).astype(int) - np.asarray(offset)
        levels.append(float(np.median(luminance(hdr[uv[:, 1], uv[:, 0]]))))
    return levels[0], levels[1]


@dataclasses.dataclass(frozen=True)
class CaseRender:
    """One case rendered through the whole pipeline.

    Attributes
    ----------
    result : ConfigResult
        Detections, corners (px) and poses (m, rad) of the experiment's tags.
    gray : ndarray of uint8 (H, W)
        The 8-bit grey crop the detector saw.
    offset : tuple of int
        The crop's top-left pixel in the full image (px).
    treatments : tuple of str
        The converged render's sticker treatments (empty when path traced).
    seconds : float
        Wall time of the render, frame, detection and pose (s).
    """

    result: ConfigResult
    gray: np.ndarray
    offset: tuple[int, int]
    treatments: tuple[str, ...]
    seconds: float


def render_case(pipe: VariantPipeline, case: SunCase) -> CaseRender:
    """Run ``case`` through ``pipe`` (its cache empty for this render)."""
    before = Counter(pipe.sticker_treatments)
    t0 = time.perf_counter()
    result = pipe.run(case.p, case.theta, 0, 0)
    seconds = time.perf_counter() - t0
    frame = pipe.frame(case.p, case.theta, 0, 0)
    treatments = tuple((pipe.sticker_treatments - before).elements())
    return CaseRender(result, frame.gray_crop, frame.offset, treatments, seconds)


def case_pipelines(exp: Experiment, cache: Path) -> dict[str, VariantPipeline]:
    """The experiment's pipelines by variant name."""
    names = [spec.name for spec in exp.variant_specs()]
    return dict(zip(names, experiment_pipelines(exp, cache), strict=True))


def corner_distance(a: ConfigResult, b: ConfigResult, index: int) -> tuple[float, float]:
    """Max and RMS distance of the four detected corners of tag ``index`` (px; NaN if missed)."""
    d = np.linalg.norm(a.corners[index] - b.corners[index], axis=-1)
    return float(np.max(d)), float(np.sqrt(np.mean(d**2)))


def pose_difference(a: ConfigResult, b: ConfigResult, index: int) -> tuple[float, float]:
    """Translation distance (mm) and rotation angle (mrad) between two estimated poses."""
    pa, pb = a.estimated[index], b.estimated[index]
    if not (np.isfinite(pa).all() and np.isfinite(pb).all()):
        return float("nan"), float("nan")
    relative = tf.rotvec_to_matrix(pa[3:]).T @ tf.rotvec_to_matrix(pb[3:])
    angle = float(np.linalg.norm(tf.matrix_to_rotvec(relative)))
    return float(np.linalg.norm(pa[:3] - pb[:3]) * 1e3), angle * 1e3


def mean_result(results: list[ConfigResult]) -> ConfigResult:
    """The mean corners and pose of several renders (rotation vectors averaged, which holds
    while they agree: a flip beyond ``FLIP_RAD`` gives NaN)."""
    estimated = np.mean([r.estimated for r in results], axis=0)
    spread = np.ptp([r.estimated[:, 3:] for r in results], axis=0).max(axis=-1)
    estimated[spread > FLIP_RAD] = np.nan
    corners = np.mean([r.corners for r in results], axis=0)
    return dataclasses.replace(results[0], estimated=estimated, corners=corners)


def sticker_mask(case: SunCase, shape: tuple[int, int], offset: tuple[int, int]) -> np.ndarray:
    """The crop's pixels whose centre lies on the sticker (bool, ``shape``)."""
    outline = projected_sticker_outlines(load_rig(), case.p, case.theta)[case.tag]
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.round((outline - offset) * 16).astype(np.int32)], 1, shift=4)
    return mask.astype(bool)


def compared(
    case: SunCase,
    tags: tuple[int, ...],
    a: CaseRender,
    b: CaseRender,
    label: str,
    pixels: bool = True,
) -> None:
    """Print ``a`` against ``b`` (``label``): corners (px), pose (mm, mrad) and, with
    ``pixels``, the sticker's pixels (DN)."""
    index = tags.index(case.tag)
    detected = bool(a.result.detected[index] and b.result.detected[index])
    corner_max, corner_rms = corner_distance(a.result, b.result, index)
    translation, rotation = pose_difference(a.result, b.result, index)
    mask = sticker_mask(case, a.gray.shape, a.offset)
    dn = a.gray[mask].astype(float) - b.gray[mask].astype(float)
    dn_rms, dn_max = float(np.sqrt(np.mean(dn**2))), float(np.abs(dn).max())
    if detected:
        bars = np.array([corner_max, translation, rotation]) / np.array(BARS)
        verdict = "within the bars" if np.all(bars <= 1) else f"{bars.max():.1f}x a bar"
        accuracy = (
            f"corners max {corner_max:.3f} RMS {corner_rms:.3f} px; pose {translation:.3f} mm "
            f"{rotation:.2f} mrad ({verdict})"
        )
    else:
        accuracy = "not detected in both"
    bright = float(np.mean(dn > FIREFLY_DN))
    shown = (
        f"; sticker DN RMS {dn_rms:.2f} max {dn_max:.0f}, {bright:.2%} > {FIREFLY_DN:g} DN above"
        if pixels
        else ""
    )
    print(f"    {label}: {accuracy}{shown}", flush=True)


def search(scene: FixtureScene, rig: Rig) -> None:
    """Print every (p, theta, azimuth, elevation) of a small grid shadowing 20-80 % of a sticker."""
    for p in (0, 3, 6):
        for theta_deg in (340.0, 350.0, 0.0, 10.0, 20.0):
            for tag in rig.tags.ids:
                if not rig.is_visible(tag, p, np.radians(theta_deg)):
                    continue
                scene.set_pose(p, np.radians(theta_deg))
                found = []
                for azimuth in (170.0, 175.0, 180.0, 185.0, 190.0, 195.0):
                    for elevation in (1.0, 2.0, 3.0, 5.0, 8.0):
                        case = SunCase("", p, theta_deg, azimuth, elevation, tag)
                        share = shadowed_share(scene, case)
                        if 0.2 <= share <= 0.8:
                            found.append(f"{azimuth:g}/{elevation:g}: {share:.0%}")
                print(f"p {p} theta {theta_deg:g} tag {tag}: " + ", ".join(found), flush=True)


def short_treatment(treatment: str) -> str:
    """``"fallback (<why>): 16 spp"`` as ``"fallback, 16 spp"``; ``"smooth"`` as it is."""
    if not treatment.startswith("fallback"):
        return treatment
    return "fallback, " + treatment.rsplit(": ", 1)[-1]


def figure(
    path: Path,
    case: SunCase,
    sky: float,
    scene: FixtureScene,
    renders: dict[str, CaseRender],
    ref_spp: int,
) -> None:
    """Converged frame, reference and their difference (DN) around the sticker, with the
    geometric shadow boundary over each (``sky``: the sky's radiance, W m^-2 sr^-1; ``ref_spp``:
    the reference's samples per pixel)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    conv, ref = renders["converged"], renders["reference"]
    treated = ", ".join(short_treatment(t) for t in conv.treatments) or "path"
    scene.set_pose(case.p, case.theta)
    boundary = sticker_to_image(scene, case.tag, shadow_boundary(scene, case)) - conv.offset
    outline = projected_sticker_outlines(load_rig(), case.p, case.theta)[case.tag] - conv.offset
    (u0, v0), (u1, v1) = np.floor(outline.min(0)) - 6, np.ceil(outline.max(0)) + 6
    u0, v0 = int(max(u0, 0)), int(max(v0, 0))
    window = (slice(v0, int(v1)), slice(u0, int(u1)))
    diff = conv.gray.astype(float) - ref.gray.astype(float)
    # the scale of most pixels: a firefly of the 16-spp fallback saturates it
    limit = max(float(np.percentile(np.abs(diff[window]), 99.5)), 4.0)
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.4), constrained_layout=True)
    panels = (
        (conv.gray, f"converged 4 spp ({treated})", "gray", 0, 255),
        (ref.gray, f"reference: path traced {ref_spp} spp", "gray", 0, 255),
        (diff, "converged - reference (DN)", "RdBu_r", -limit, limit),
    )
    for ax, (img, title, cmap, lo, hi) in zip(axes, panels, strict=True):
        shown = ax.imshow(img[window], cmap=cmap, vmin=lo, vmax=hi, interpolation="nearest",
                          extent=(u0 - 0.5, int(u1) - 0.5, int(v1) - 0.5, v0 - 0.5))  # fmt: skip
        ax.plot(boundary[:, 0], boundary[:, 1], ".", ms=1.5, color="tab:orange",
                label="geometric shadow boundary")  # fmt: skip
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("crop column (px)")
        if img is diff:
            fig.colorbar(shown, ax=ax, shrink=0.8)
    axes[0].set_ylabel("crop row (px)")
    axes[0].legend(loc="lower left", fontsize=8, markerscale=6)
    fig.suptitle(
        f"{case.name}: p {case.p}, theta {case.theta_deg:g} deg, sun azimuth "
        f"{case.azimuth_deg:g} deg elevation {case.elevation_deg:g} deg, sky {sky:g} "
        f"W m^-2 sr^-1, tag {case.tag}"
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"figure: {path}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--skies", default="0,200", help="sky radiances (W m^-2 sr^-1)")
    # 1024 spp is biased under a sun on bare metal (docs/results/shadow_edge.md)
    parser.add_argument("--ref-spp", type=int, default=4096)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--seeds", type=int, default=2, help="converged render seeds 0..N-1")
    parser.add_argument(
        "--path-spp", default="16,256", help="also path traced at these spp (render seed 0)"
    )
    parser.add_argument("--cases", default=",".join(c.name for c in CASES))
    parser.add_argument("--figure", type=Path, default=None, help="PNG of one case")
    parser.add_argument("--figure-case", default=CASES[1].name)
    parser.add_argument("--figure-sky", type=float, default=200.0)
    parser.add_argument("--search", action="store_true", help="list candidate cases and stop")
    parser.add_argument(
        "--effects", type=json.loads, default=None, help="JSON: more effects for every case"
    )
    args = parser.parse_args()
    cases = tuple(c for c in CASES if c.name in args.cases.split(","))
    skies = [float(s) for s in args.skies.split(",")]
    if args.figure is not None and args.figure_sky not in skies:
        parser.error(f"--figure-sky {args.figure_sky:g}: expected one of --skies")

    with tempfile.TemporaryDirectory(prefix="simgap-bench-") as tmp:
        if args.search:
            exp = sun_experiment(cases, skies[0], extra=args.effects)
            search(case_pipelines(exp, Path(tmp))[cases[0].name].scene(), exp.rig_model)
            return
        for sky in skies:
            exp = sun_experiment(cases, sky, extra=args.effects)
            tags = tuple(int(t) for t in exp.configuration_axes()[2])
            runs = {
                f"reference seed {s}": exp.with_render(spp=args.ref_spp, mode="path", seed=s)
                for s in (0, 1)
            }
            for s in range(args.seeds):
                runs[f"converged seed {s}"] = exp.with_render(
                    spp=args.spp, mode="converged", seed=s
                )
            for n in (int(v) for v in args.path_spp.split(",") if v):
                runs[f"path {n} spp"] = exp.with_render(spp=n, mode="path", seed=0)
            pipes = {label: case_pipelines(e, Path(tmp)) for label, e in runs.items()}
            print(f"sky {sky:g} W m^-2 sr^-1, exposure gain {exp.image.exposure:.3g}:", flush=True)
            for case in cases:
                renders = {label: render_case(p[case.name], case) for label, p in pipes.items()}
                ref_pipe = pipes["reference seed 0"][case.name]
                scene = ref_pipe.scene()
                scene.set_pose(case.p, case.theta)
                hdr, offset = ref_pipe.hdr(case.p, case.theta, 0)
                lit, shade = paper_levels(scene, case, hdr, offset)
                seconds = ", ".join(f"{k} {r.seconds:.1f} s" for k, r in renders.items())
                print(
                    f"  {case.name}: p {case.p}, theta {case.theta_deg:g} deg, sun "
                    f"{case.azimuth_deg:g}/{case.elevation_deg:g} deg; tag {case.tag} "
                    f"{shadowed_share(scene, case):.0%} shadowed; shadowed / lit paper "
                    f"{shade / lit:.3f} ({seconds})",
                    flush=True,
                )
                ref0, ref1 = renders["reference seed 0"], renders["reference seed 1"]
                mean_ref = dataclasses.replace(ref0, result=mean_result([ref0.result, ref1.result]))
                compared(case, tags, ref1, ref0, "reference seed 1 against seed 0")
                for label, render in renders.items():
                    if label.startswith("reference"):
                        continue
                    print(f"    {label}: {'; '.join(render.treatments) or 'path'}", flush=True)
                    compared(case, tags, render, ref0, "  against reference seed 0")
                    if label.startswith("converged"):
                        compared(case, tags, render, mean_ref, "  against the mean", False)
                drawn = (case.name, sky) == (args.figure_case, args.figure_sky)
                if args.figure is not None and drawn:
                    shown = {"converged": renders["converged seed 0"], "reference": ref0}
                    figure(args.figure, case, sky, scene, shown, args.ref_spp)


if __name__ == "__main__":
    main()
