"""The renderer obeys OpenCV's camera model, and crop rendering equals full-frame rendering."""

from __future__ import annotations

import numpy as np
import pytest

from simgap.pipeline.variant import crop_offset
from simgap.pose.detect import Detector, DetectorSettings
from simgap.pose.estimate import estimate_pose, pose_error, project_tag_corners
from simgap.render import imaging
from simgap.render.backend import mitsuba
from simgap.render.camera import PLUGIN_NAME
from simgap.render.scene import FixtureScene, load_scene_spec, projected_sticker_boxes


def _sphere_scene(size, spp=64):
    mi = mitsuba()
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "direct"},
            "sensor": {
                "type": PLUGIN_NAME,
                "film": {
                    "type": "hdrfilm",
                    "width": size[0],
                    "height": size[1],
                    "rfilter": {"type": "box"},
                },
                "sampler": {"type": "multijitter", "sample_count": spp},
            },
            "ball": {
                "type": "sphere",
                "center": [0.0, 0.0, 0.0],
                "radius": 0.0015,
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1.0}},
            },
        }
    )


@pytest.mark.parametrize(
    "fx, fy, cx, cy, dist, point",
    [
        (1386.0, 1386.0, 959.5, 539.5, (0, 0, 0, 0, 0), (0.05, 0.02, 0.3)),
        (1386.0, 1386.0, 959.5, 539.5, (0, 0, 0, 0, 0), (-0.12, -0.06, 0.35)),
        (1413.7, 1390.2, 949.0, 551.3, (0, 0, 0, 0, 0), (0.08, -0.04, 0.4)),
        (1386.0, 1386.0, 959.5, 539.5, (0.12, -0.25, 0.001, -0.0008, 0.1), (-0.15, 0.08, 0.3)),
    ],
)
def test_sphere_centre_lands_on_projectpoints(fx, fy, cx, cy, dist, point):
    """A small glowing sphere's centroid matches cv2.projectPoints within 0.1 px (issue 2)."""
    import cv2

    size = (64, 64)
    scene = _sphere_scene(size)
    cam = scene.sensors()[0]
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    uv, _ = cv2.projectPoints(
        np.array([point], float), np.zeros(3), np.zeros(3), K, np.array(dist, float)
    )
    u, v = uv.ravel()
    x0, y0 = int(u) - size[0] // 2 + 3, int(v) - size[1] // 2 - 2  # off-centre crop on purpose
    cam.set_intrinsics(fx, fy, cx, cy, dist)
    # camera at -point looking along +z: the sphere (origin) sits at `point` in the camera frame
    pose = np.eye(4)
    pose[:3, 3] = -np.asarray(point)
    cam.set_pose(pose)
    cam.set_crop_offset(x0, y0)
    img = np.array(mitsuba().render(scene, seed=1))[..., 0]
    yy, xx = np.mgrid[0 : size[1], 0 : size[0]]
    cu = (img * xx).sum() / img.sum() + x0
    cv_ = (img * yy).sum() / img.sum() + y0
    # measured: <= 0.03 px (perspective foreshortening of the 3 mm sphere); the issue asks < 0.1 px
    assert abs(cu - u) < 0.1 and abs(cv_ - v) < 0.1, (cu - u, cv_ - v)


@pytest.fixture(scope="module")
def ideal_render(rig):
    """Tag 0 at p=0, theta=0: 128 spp crop, no noise, sRGB 8-bit frame."""
    spec = load_scene_spec()
    side = 288
    scene = FixtureScene(rig, spec, (side, side), spp=128)
    boxes = projected_sticker_boxes(rig, 0, 0.0)
    offset = crop_offset(boxes, (side, side), (rig.camera.width, rig.camera.height))
    scene.set_pose(0, 0.0)
    hdr = imaging.quantise_half(scene.render(offset, seed=7))
    return scene, hdr, offset


def test_ideal_render_pose_accuracy(rig, ideal_render):
    """Ideal render, SUBPIX: corners < 0.3 px, |t| < 0.5 mm per axis, |rx|, |ry| < 0.02 rad."""
    _, hdr, offset = ideal_render
    frame = imaging.paste(imaging.encode_srgb8(hdr), offset, (rig.camera.width, rig.camera.height))
    found = Detector(DetectorSettings(corner_refinement="SUBPIX")).detect(imaging.to_gray(frame))
    assert 0 in found and 1 not in found
    cam = rig.camera
    truth = project_tag_corners(
        rig.eyepoint_from_tag(0, 0, 0.0), rig.tags.size, cam.matrix, cam.dist_coeffs
    )
    # measured 0.20 px max (the sRGB curve pulls the black square's edges inward by ~0.2 px)
    assert np.abs(found[0] - truth).max() < 0.3
    est = estimate_pose(found[0], rig.tags.size, cam.matrix, cam.dist_coeffs)
    err = pose_error(est.pose, rig.expected_pose(0, 0, 0.0))
    # measured: |t| <= 0.42 mm (ty), |rx|, |ry| <= 0.003 rad
    assert np.all(np.abs(err[:3]) < 0.0005), err
    assert abs(err[3]) < 0.02 and abs(err[4]) < 0.02, err


def test_same_seed_same_render(rig):
    """The box filter + multijitter sampler make renders bit-identical for the same seed.

    A small film at few samples: determinism does not depend on either (the 128-spp crop of
    ``ideal_render`` took 28 s for the same check).
    """
    scene = FixtureScene(rig, load_scene_spec(), (96, 96), spp=4)
    box = projected_sticker_boxes(rig, 0, 0.0)[0]  # the film's top-left on the sticker's
    offset = (int(box[0]), int(box[1]))
    scene.set_pose(0, 0.0)
    first = imaging.quantise_half(scene.render(offset, seed=7))
    assert first.max() > 0  # the sticker is in view
    assert np.array_equal(first, imaging.quantise_half(scene.render(offset, seed=7)))
    assert not np.array_equal(first, imaging.quantise_half(scene.render(offset, seed=8)))


def test_crop_pasted_into_frame_detects_like_full_frame(rig):
    """Detection on a crop pasted into a full-size frame equals detection on the full frame.

    The same full-frame render is used both ways, so only the pasting differs.
    """
    scene = FixtureScene(rig, load_scene_spec(), (rig.camera.width, rig.camera.height), spp=4)
    size = (rig.camera.width, rig.camera.height)
    for tag, p, theta in [(0, 0, 0.0), (1, 7, np.deg2rad(200))]:
        scene.set_pose(p, theta)
        full = imaging.encode_srgb8(imaging.quantise_half(scene.render((0, 0), seed=3)))
        off = crop_offset(projected_sticker_boxes(rig, p, theta), (288, 288), size)
        crop = full[off[1] : off[1] + 288, off[0] : off[0] + 288]
        pasted = imaging.paste(crop, off, size)
        for refinement in ("SUBPIX", "NONE"):
            det = Detector(DetectorSettings(corner_refinement=refinement))
            a = det.detect(imaging.to_gray(full))
            b = det.detect(imaging.to_gray(pasted))
            assert tag in a and tag in b
            # measured: identical corners (0 px); allow float round-off only
            assert np.abs(a[tag] - b[tag]).max() < 1e-6


def test_exr_round_trip(tmp_path):
    hdr = np.random.default_rng(0).random((8, 9, 3)).astype(np.float32) * 4
    imaging.write_exr(tmp_path / "a.exr", hdr)
    back = imaging.read_exr(tmp_path / "a.exr")
    assert np.array_equal(back, imaging.quantise_half(hdr))
    assert not list(tmp_path.glob("*.tmp*"))


def test_srgb_encoding_matches_standard():
    # sRGB: 0.0031308 -> 12.92 * x; 0.5 linear -> 0.7354 encoded -> 188 in 8 bits (IEC 61966-2-1)
    out = imaging.encode_srgb8(np.array([0.0, 0.0031308, 0.5, 1.0, 2.0]))
    assert out.tolist() == [0, 10, 188, 255, 255]
