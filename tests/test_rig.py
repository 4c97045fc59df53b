"""Tests of simgap.core.rig: the transform tree against the paper's Table 1, orientations, fixture
errors, visibility and strict loading of rig overrides."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from simgap.core import transforms as tf
from simgap.core.config import ConfigError
from simgap.core.rig import FixtureErrors, load_rig

# Table 1 of the paper (docs/conventions.md §1), eyepoint to tag centre (m).
TABLE1_X0 = 0.0325
TABLE1_Y0 = 0.28314414
TABLE1_Z = -0.01616866
PITCH = 0.0254
RADIUS = {0: 0.0806, 1: 0.0381}

# The transform tree is a handful of float64 additions and 3x3 products of numbers of order 0.1 m,
# so it agrees with the closed-form table to ~1e-16 m; 1e-9 m leaves room for the rounding of the
# tree's link values (the links sum to Table 1 exactly in decimal) while catching any real slip.
TABLE_TOL_M = 1e-9
# Pure float64 algebra on unit vectors / O(0.1 m) lengths: errors are a few ulp (~1e-16).
EXACT_TOL = 1e-12

PS = (0, 7, 14)
THETAS_DEG = (0, 10, 95, 180, 275, 350)


@pytest.fixture(scope="module")
def rig():
    return load_rig()


def table1(tag: int, p: float, theta: float) -> np.ndarray:
    r = RADIUS[tag]
    return np.array(
        [
            TABLE1_X0 + r * np.sin(theta),
            TABLE1_Y0 + PITCH * p - r * np.cos(theta),
            TABLE1_Z,
        ]
    )


def normal0(theta: float) -> np.ndarray:
    """Outward normal of tag 0's face (docs/conventions.md §1)."""
    return np.array([np.sin(theta), -np.cos(theta), 0.0])


@pytest.mark.parametrize("tag", [0, 1])
@pytest.mark.parametrize("p", PS)
@pytest.mark.parametrize("theta_deg", THETAS_DEG)
def test_table1_tag_centre(rig, tag, p, theta_deg):
    theta = np.deg2rad(theta_deg)
    got = rig.eyepoint_from_tag(tag, p, theta)[:3, 3]
    np.testing.assert_allclose(got, table1(tag, p, theta), rtol=0, atol=TABLE_TOL_M)


@pytest.mark.parametrize("tag", [0, 1])
@pytest.mark.parametrize("theta_deg", THETAS_DEG)
def test_marker_frame_orientation(rig, tag, theta_deg):
    theta = np.deg2rad(theta_deg)
    r = rig.eyepoint_from_tag(tag, 7, theta)[:3, :3]
    x, y, z = r[:, 0], r[:, 1], r[:, 2]
    n = normal0(theta) if tag == 0 else -normal0(theta)
    np.testing.assert_allclose(z, n, rtol=0, atol=EXACT_TOL)
    np.testing.assert_allclose(y, [0.0, 0.0, 1.0], rtol=0, atol=EXACT_TOL)
    np.testing.assert_allclose(x, np.cross(y, z), rtol=0, atol=EXACT_TOL)
    # Proper rotation: orthonormal with determinant +1.
    np.testing.assert_allclose(r @ r.T, np.eye(3), rtol=0, atol=EXACT_TOL)
    assert abs(np.linalg.det(r) - 1.0) < EXACT_TOL
    tf.check_transform(rig.eyepoint_from_tag(tag, 7, theta))


@pytest.mark.parametrize("tag", [0, 1])
@pytest.mark.parametrize("theta_deg", THETAS_DEG)
def test_expected_pose_round_trip(rig, tag, theta_deg):
    theta = np.deg2rad(theta_deg)
    m = rig.eyepoint_from_tag(tag, 14, theta)
    pose = rig.expected_pose(tag, 14, theta)
    assert pose.shape == (6,)
    np.testing.assert_allclose(pose[:3], m[:3, 3], rtol=0, atol=EXACT_TOL)
    # Rotation vector -> matrix goes through scipy's quaternion maths (sin/cos/atan2), still
    # float64 to a few ulp; the rotation angle reaches pi here (tag 1 at theta=0), where
    # matrix->rotvec is least well conditioned, so use 1e-9 rather than 1e-12.
    np.testing.assert_allclose(tf.rotvec_to_matrix(pose[3:]), m[:3, :3], rtol=0, atol=1e-9)
    assert np.linalg.norm(pose[3:]) <= np.pi + 1e-12


def test_turntable_zero_equals_shifted_theta(rig):
    d = np.deg2rad(1.7)
    err = FixtureErrors(turntable_zero=d)
    for tag, p, theta_deg in itertools.product((0, 1), PS, THETAS_DEG):
        theta = np.deg2rad(theta_deg)
        got = rig.eyepoint_from_tag(tag, p, theta, err)
        want = rig.eyepoint_from_tag(tag, p, theta + d)
        np.testing.assert_allclose(got, want, rtol=0, atol=EXACT_TOL)


def test_pitch_scale_moves_tag_y(rig):
    s = 0.01
    err = FixtureErrors(pitch_scale=s)
    for tag, p, theta_deg in itertools.product((0, 1), PS, THETAS_DEG):
        theta = np.deg2rad(theta_deg)
        got = rig.eyepoint_from_tag(tag, p, theta, err)
        nominal = rig.eyepoint_from_tag(tag, p, theta)
        np.testing.assert_allclose(
            got[:3, 3] - nominal[:3, 3], [0.0, PITCH * p * s, 0.0], rtol=0, atol=EXACT_TOL
        )
        np.testing.assert_allclose(got[:3, :3], nominal[:3, :3], rtol=0, atol=EXACT_TOL)


def test_mount_translation_shifts_tag_opposite(rig):
    d = np.array([0.001, -0.002, 0.003])
    err = FixtureErrors(mount_translation=tuple(d))
    for tag, p, theta_deg in itertools.product((0, 1), PS, THETAS_DEG):
        theta = np.deg2rad(theta_deg)
        got = rig.eyepoint_from_tag(tag, p, theta, err)
        nominal = rig.eyepoint_from_tag(tag, p, theta)
        # The camera moved by d, so the tag, seen from the camera, moved by -d.
        np.testing.assert_allclose(got[:3, 3] - nominal[:3, 3], -d, rtol=0, atol=EXACT_TOL)
        np.testing.assert_allclose(got[:3, :3], nominal[:3, :3], rtol=0, atol=EXACT_TOL)


def test_visibility_at_facing_angles(rig):
    assert rig.is_visible(0, 0, 0.0)
    assert not rig.is_visible(0, 0, np.pi)
    assert not rig.is_visible(1, 0, 0.0)
    assert rig.is_visible(1, 0, np.pi)


def test_never_both_tags_visible(rig):
    # The two tag planes face opposite ways (n1 = -n0) and tag 1 is nearer the axis, so the
    # camera can never be in front of both at once.
    both = []
    counts = {0: 0, 1: 0}
    for p, theta in itertools.product(rig.grid.p, rig.grid.theta):
        vis = [rig.is_visible(tag, p, theta) for tag in (0, 1)]
        for tag, v in zip((0, 1), vis, strict=True):
            counts[tag] += v
        if all(vis):
            both.append((p, float(np.rad2deg(theta))))
    assert both == []
    # Each tag is visible somewhere on the grid (sanity: the test is not vacuous).
    assert counts[0] > 0 and counts[1] > 0


def test_override_wrong_type_names_key():
    with pytest.raises(ConfigError) as info:
        load_rig(overrides={"camera": {"fx": "abc"}})
    msg = str(info.value)
    assert "camera.fx" in msg
    assert "expected a number" in msg


def test_override_unknown_key_named():
    with pytest.raises(ConfigError) as info:
        load_rig(overrides={"camera": {"fxx": 1.0}})
    assert "camera.fxx" in str(info.value)
    assert "unknown key" in str(info.value)


def test_override_negative_pitch_rejected():
    with pytest.raises(ConfigError) as info:
        load_rig(overrides={"links": {"pin_pitch": -0.0254}})
    assert "pin_pitch" in str(info.value)
    assert "rig.yaml" in str(info.value)


def test_override_valid_value_applied():
    rig = load_rig(overrides={"camera": {"fx": 1400}})
    assert rig.camera.fx == 1400.0
    assert isinstance(rig.camera.fx, float)
    assert rig.camera.fy == 1386.0


def test_batched_transform_tree_matches_the_single_one():
    rig = load_rig()
    err = FixtureErrors(
        mount_translation=(0.002, -0.001, 0.003),
        mount_rotation=(0.01, -0.02, 0.005),
        turntable_zero=0.03,
        pitch_scale=0.02,
        tag_offset=(0.001, 0.002, -0.001),
    )
    rows = [(t, p, th) for t in (0, 1) for p in (0, 7, 14) for th in np.deg2rad([0, 95, 250])]
    tags, ps, thetas = map(np.array, zip(*rows, strict=True))
    batch = rig.eyepoints_from_tags(tags, ps, thetas, err)
    single = np.stack([rig.eyepoint_from_tag(int(t), p, th, err) for t, p, th in rows])
    # same products in another order: float64 round-off only (measured 1e-16)
    np.testing.assert_allclose(batch, single, atol=1e-12)
