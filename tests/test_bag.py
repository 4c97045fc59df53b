"""Tests of ROS bags in and out (simgap.pipeline.bag), without ROS: bags are written by rosbags
itself (through simgap's exporter and directly in the tests), read back and ingested. The frames are
synthetic: the rig's tag textures warped to where the rig's geometry projects the stickers, so
OpenCV's real detector finds the tags; one test renders a frame through the cached pipeline."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer as Writer1
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from simgap.cli import app
from simgap.core import transforms as tf
from simgap.core.config import ConfigError
from simgap.pipeline.bag import (
    CAMERA_INFO_TOPIC,
    FIXTURE_TOPIC,
    IMAGE_TOPIC,
    TF_STATIC_TOPIC,
    TF_TOPIC,
    bag_to_capture,
    capture_to_bag,
    ingest_bag,
)
from simgap.pipeline.bag.messages import Messages
from simgap.pipeline.capture import ingest, write_capture
from simgap.pose.estimate import project_tag_corners
from simgap.render.assets import tag_texture
from simgap.results.dataset import write_netcdf
from tests.cf_check import assert_cf_valid

#: (p, theta deg, repeat): tag 0 faces the camera at 0/30 deg, tag 1 at 180/200 deg
CONFIGS = [(0, 0, 0), (7, 30, 0), (3, 180, 0), (14, 200, 0), (0, 0, 1)]


def synthetic_frame(rig, p: int, theta: float, shift_px: float = 0.0) -> np.ndarray:
    """An 8-bit RGB frame with the visible tags' textures warped onto their projected stickers."""
    cam = rig.camera
    gray = np.full((cam.height, cam.width), 128, np.uint8)
    for tag in rig.tags.ids:
        if not rig.is_visible(tag, p, theta):
            continue
        texture = tag_texture(rig.tags.dictionary, tag, rig.tags.quiet_zone_cells)
        texture = cv2.resize(texture, (256, 256), interpolation=cv2.INTER_NEAREST)
        m = rig.eyepoint_from_tag(tag, p, theta)
        dst = project_tag_corners(m, rig.sticker_size(), cam) + shift_px
        src = np.array([[0, 0], [256, 0], [256, 256], [0, 256]], np.float32) - 0.5
        h = cv2.getPerspectiveTransform(src, dst.astype(np.float32))
        warped = cv2.warpPerspective(texture, h, (cam.width, cam.height), flags=cv2.INTER_AREA)
        mask = cv2.warpPerspective(np.full_like(texture, 255), h, (cam.width, cam.height))
        gray = np.where(mask > 127, warped, gray)
    return cv2.cvtColor(gray, cv2.COLOR_GRAY2RGB)


@pytest.fixture(scope="module")
def frames(rig):
    return [
        (p, math.radians(deg), r, synthetic_frame(rig, p, math.radians(deg), 0.3 * r))
        for p, deg, r in CONFIGS
    ]


@pytest.fixture(scope="module")
def png_capture(tmp_path_factory, frames, rig):
    folder = tmp_path_factory.mktemp("png") / "capture"
    write_capture(folder, frames, rig.camera)
    return folder


@pytest.fixture(scope="module")
def png_ds(png_capture):
    return ingest(png_capture)


def assert_same_data(a, b):
    assert set(a.data_vars) == set(b.data_vars)
    for name in a.data_vars:
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)
    for name in a.coords:
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def test_synthetic_frames_are_detected(png_ds):
    det = png_ds.detected.values[0]
    assert det.sum() == 5  # one visible tag per frame, every one found
    # the poses are real estimates: measured max translation error 5.5 mm (p=14, 0.55 m away)
    assert np.nanmax(np.abs(png_ds.error.values[..., :3])) < 1e-2


@pytest.mark.parametrize(
    "fmt,compressed", [("ros1", False), ("ros2", False), ("ros1", True), ("ros2", True)]
)
def test_round_trip_capture_bag_ingest(tmp_path, png_capture, png_ds, fmt, compressed):
    bag = tmp_path / ("out.bag" if fmt == "ros1" else "out")
    capture_to_bag(png_capture, bag, fmt, images="png" if compressed else "raw")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # atomic: no leftovers
    ds = ingest_bag(bag)
    assert_same_data(png_ds, ds)
    assert ds.attrs["source"] == "bag" and ds.attrs["bag_format"] == fmt
    assert ds.attrs["bag_fixture_source"] == f"topic {FIXTURE_TOPIC}"


def test_jpeg_bytes_are_kept(tmp_path, frames, rig):
    folder = tmp_path / "jpeg"
    write_capture(folder, frames, rig.camera, image_format="jpg", jpeg_quality=90)
    capture_to_bag(folder, tmp_path / "bag", "ros2", images="jpeg")
    kept = tmp_path / "kept"
    ds = ingest_bag(tmp_path / "bag", keep_capture=kept)
    for image in sorted((folder / "images").iterdir()):
        assert (kept / "images" / image.name).read_bytes() == image.read_bytes()
    assert_same_data(ingest(folder), ds)
    assert_cf_valid(write_netcdf(ds, tmp_path / "bag.nc"))  # a bag's dataset is CF-1.10 too


def test_bag_contents(tmp_path, png_capture, rig):
    bag = tmp_path / "c.bag"
    capture_to_bag(png_capture, bag, "ros1")
    with AnyReader([bag]) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        assert topics[IMAGE_TOPIC] == "sensor_msgs/msg/Image"
        assert topics[CAMERA_INFO_TOPIC] == "sensor_msgs/msg/CameraInfo"
        assert topics["/simgap/tag0/expected"] == "geometry_msgs/msg/PoseStamped"
        conns = [c for c in reader.connections if c.topic == "/simgap/tag0/expected"]
        conn, _, raw = next(iter(reader.messages(connections=conns)))
        msg = reader.deserialize(raw, conn.msgtype)
    # frame 0 is p=0, theta=0: the ground truth in the optical frame (x right, y down, z fwd)
    t = rig.eyepoint_from_tag(0, 0, 0.0)[:3, 3]
    pos = msg.pose.position
    np.testing.assert_allclose([pos.x, pos.y, pos.z], [t[0], -t[2], t[1]], atol=1e-12)
    assert msg.header.frame_id == "camera_color_optical_frame"


def read_transforms(reader, topic: str) -> list[dict[tuple[str, str], np.ndarray]]:
    """Each TFMessage of ``topic`` as {(parent, child): parent_from_child 4x4}."""
    conns = [c for c in reader.connections if c.topic == topic]
    out = []
    for conn, _, raw in reader.messages(connections=conns):
        links = {}
        for t in reader.deserialize(raw, conn.msgtype).transforms:
            q, v = t.transform.rotation, t.transform.translation
            r = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
            links[(t.header.frame_id, t.child_frame_id)] = tf.make(r, (v.x, v.y, v.z))
        out.append(links)
    return out


@pytest.mark.parametrize(
    "name,magic", [("c.mcap", b"\x89MCAP0\r\n"), ("c.db3", b"SQLite format 3")]
)
def test_single_file_ros2_bags_carry_the_transform_tree(
    tmp_path, png_capture, png_ds, rig, name, magic
):
    out = tmp_path / name
    res = CliRunner().invoke(app, ["export-bag", str(png_capture), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert out.is_file() and out.read_bytes().startswith(magic)  # one real file of that storage
    assert [p.name for p in tmp_path.iterdir()] == [name]
    with AnyReader([out]) as reader:
        (static,) = read_transforms(reader, TF_STATIC_TOPIC)
        moving = read_transforms(reader, TF_TOPIC)
    # the rig's CAD links, float64 all the way: equal to 1e-9 (m and rotation matrix entries)
    want = {
        ("carriage", "eyepoint"): rig.carriage_from_eyepoint(),
        ("eyepoint", "camera_color_optical_frame"): tf.make(tf.GLOBAL_FROM_CV),
        ("turntable", "tag0"): rig.turntable_from_tag(0),
        ("turntable", "tag1"): rig.turntable_from_tag(1),
    }
    assert static.keys() == want.keys()
    for key, m in want.items():
        np.testing.assert_allclose(static[key], m, atol=1e-9, err_msg=str(key))
    assert len(moving) == len(CONFIGS)
    for links, (p, deg, _) in zip(moving, CONFIGS, strict=True):
        theta = math.radians(deg)
        np.testing.assert_allclose(
            links[("rail", "carriage")], rig.rail_from_carriage(p), atol=1e-9
        )
        np.testing.assert_allclose(
            links[("rail", "turntable")], rig.rail_from_turntable(theta), atol=1e-9
        )
        # the tree gives the expected pose: rail -> carriage -> eyepoint vs rail -> turntable -> tag
        rail_from_eye = links[("rail", "carriage")] @ static[("carriage", "eyepoint")]
        eye_from_tag = (
            tf.invert(rail_from_eye) @ links[("rail", "turntable")] @ static[("turntable", "tag0")]
        )
        np.testing.assert_allclose(eye_from_tag, rig.eyepoint_from_tag(0, p, theta), atol=1e-9)
    assert_same_data(png_ds, ingest_bag(out))


def test_bag_names_decide_the_storage(tmp_path, png_capture):
    runner = CliRunner()
    folder = tmp_path / "mcap_folder"
    res = runner.invoke(
        app, ["export-bag", str(png_capture), "-o", str(folder), "--storage", "mcap"]
    )
    assert res.exit_code == 0, res.output
    assert "storage_identifier: mcap" in (folder / "metadata.yaml").read_text()
    assert (folder / "mcap_folder.mcap").is_file()
    for args, message in (
        (["-o", str(tmp_path / "x.bag2")], "extension '.bag2': expected NAME.bag (ROS 1)"),
        (["-o", str(tmp_path / "x.mcap"), "--format", "ros1"], "--format ros1"),
        (["-o", str(tmp_path / "x.mcap"), "--storage", "sqlite3"], "--storage sqlite3"),
        (["-o", str(tmp_path / "x"), "--storage", "zip"], "'zip' is not one of 'sqlite3', 'mcap'"),
    ):
        bad = runner.invoke(app, ["export-bag", str(png_capture), *args])
        assert bad.exit_code == 2 and message in bad.output, bad.output
        assert "Traceback" not in bad.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mcap_folder"]


def write_raw_bag(path: Path, rig, frames, stamps_ns, extra_image_topic: bool = False) -> Path:
    """A ROS 1 bag written directly with rosbags: raw frames and a CameraInfo, no fixture topic."""
    build = Messages("ros1")
    with Writer1(path) as writer:
        img = writer.add_connection(IMAGE_TOPIC, "sensor_msgs/msg/Image", typestore=build.ts)
        info = writer.add_connection(
            CAMERA_INFO_TOPIC, "sensor_msgs/msg/CameraInfo", typestore=build.ts
        )
        other = None
        if extra_image_topic:
            other = writer.add_connection(
                "/other/image", "sensor_msgs/msg/Image", typestore=build.ts
            )
        for (_, _, _, rgb), ns in zip(frames, stamps_ns, strict=True):
            writer.write(info, ns, build.serialize(build.camera_info(ns, rig.camera)))
            writer.write(img, ns, build.serialize(build.image(ns, rgb, "raw")))
            if other is not None:
                writer.write(other, ns, build.serialize(build.image(ns, rgb, "raw")))
    return path


def write_ranges(path: Path, rows) -> Path:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["start_ns", "end_ns", "p", "theta_rad"])
        w.writerows(rows)
    return path


def test_time_ranges_assign_configurations(tmp_path, frames, rig, png_ds):
    stamps = [10**9 * (k + 1) for k in range(len(frames))] + [10**9 * 50]
    bag = write_raw_bag(tmp_path / "r.bag", rig, frames + [frames[0]], stamps)
    rows = [
        (stamps[k] - 10, stamps[k] + 10, p, f"{t:.6f}")
        for k, (p, t, r, _) in enumerate(frames)
        if r == 0
    ]
    # frame 4 is a second take of (p=0, theta=0), in a range of its own
    rows.append((stamps[4] - 10, stamps[4] + 10, 0, "0.0"))
    ranges = write_ranges(tmp_path / "ranges.csv", rows)
    ds = ingest_bag(bag, ranges_csv=ranges)
    assert ds.attrs["bag_frames_skipped"] == 1  # the frame at 50 s is in no range
    assert_same_data(png_ds, ds)  # the two takes of (0, 0 deg) are repeats 0 and 1


def test_cli_ingest_bag_errors(tmp_path, frames, rig):
    runner = CliRunner()
    bag = write_raw_bag(tmp_path / "a.bag", rig, frames[:1], [10**9])
    res = runner.invoke(app, ["ingest", str(bag), "-o", str(tmp_path / "x.nc")])
    assert res.exit_code == 2
    assert f"topic {FIXTURE_TOPIC}: not in the bag" in res.output
    assert len(res.output.strip().splitlines()) == 1 and "Traceback" not in res.output
    bad = write_ranges(tmp_path / "bad.csv", [(0, 10, 15, "0.0")])
    res = runner.invoke(app, ["ingest", str(bag), "--ranges", str(bad), "-o", "x.nc"])
    assert res.exit_code == 2
    assert f"{bad}: row 1 (line 2): p: expected a pin hole" in res.output
    good = write_ranges(tmp_path / "good.csv", [(0, 2 * 10**9, 0, "0.0")])
    res = runner.invoke(
        app, ["ingest", str(bag), "--ranges", str(good), "-o", str(tmp_path / "ok.nc")]
    )
    assert res.exit_code == 0, res.output
    assert "1 frame(s)" in res.output


def test_named_errors(tmp_path, frames, rig):
    two = write_raw_bag(tmp_path / "two.bag", rig, frames[:1], [10**9], extra_image_topic=True)
    good = write_ranges(tmp_path / "g.csv", [(0, 2 * 10**9, 0, "0.0")])
    with pytest.raises(ConfigError, match="several topics could hold the frames"):
        bag_to_capture(two, tmp_path / "c1", rig, good)
    with pytest.raises(ConfigError, match="topic /nope: not in the bag"):
        bag_to_capture(two, tmp_path / "c2", rig, good, image_topic="/nope")
    with pytest.raises(ConfigError, match="expected sensor_msgs/msg/Image or"):
        bag_to_capture(two, tmp_path / "c3", rig, good, image_topic=CAMERA_INFO_TOPIC)
    overlap = write_ranges(tmp_path / "o.csv", [(0, 10, 0, "0.0"), (5, 20, 7, "0.0")])
    with pytest.raises(ConfigError, match="row 2: overlaps row 1"):
        bag_to_capture(two, tmp_path / "c4", rig, overlap, image_topic=IMAGE_TOPIC)
    theta = write_ranges(tmp_path / "t.csv", [(0, 10, 0, "0.1")])
    with pytest.raises(ConfigError, match="theta_rad: expected a turntable stop"):
        bag_to_capture(two, tmp_path / "c5", rig, theta, image_topic=IMAGE_TOPIC)
    with pytest.raises(ConfigError, match="not a ROS bag"):
        ingest_bag(tmp_path / "g.csv")
    # a calibration with skew is refused, naming the topic
    skewed = rig.camera.replace(fx=1000.0)
    build = Messages("ros1")
    msg = build.camera_info(10**9, skewed)
    msg.K[1] = 5.0
    path = tmp_path / "skew.bag"
    with Writer1(path) as w:
        c = w.add_connection(CAMERA_INFO_TOPIC, "sensor_msgs/msg/CameraInfo", typestore=build.ts)
        i = w.add_connection(IMAGE_TOPIC, "sensor_msgs/msg/Image", typestore=build.ts)
        w.write(c, 10**9, build.serialize(msg))
        w.write(i, 10**9, build.serialize(build.image(10**9, frames[0][3], "raw")))
    with pytest.raises(ConfigError, match=f"topic {CAMERA_INFO_TOPIC}: message 1: camera_matrix"):
        bag_to_capture(path, tmp_path / "c6", rig, good)


def test_export_bag_from_experiment_renders_and_ingests(tmp_path, session_cache, rig):
    yaml_path = tmp_path / "one.yaml"
    yaml_path.write_text(
        "name: one\nconfigurations:\n  p: [7]\n  theta_deg: [0]\nrender:\n  spp: 16\n"
    )
    out = tmp_path / "one.bag"
    res = CliRunner().invoke(
        app, ["export-bag", str(yaml_path), "-o", str(out), "--cache", str(session_cache)]
    )
    assert res.exit_code == 0, res.output
    # the export's progress, as plain lines off a terminal (it had shown none; issue 53)
    assert "exporting frames: 0/1 after" in res.output
    assert "exporting frames: 1/1 after" in res.output
    ds = ingest_bag(out)
    assert bool(ds.detected.sel(tag=0).any())
    # rendered tag 0 at p=7 facing the camera: the depth error of a render is a few mm at most
    assert abs(float(ds.error.sel(tag=0, axis="ty").max())) < 5e-3


def _lying_bag(path: Path, rig, frames, image_stamps, joint_rows) -> Path:
    """A ROS 1 bag recorded at 1 s steps: CameraInfo, joint states ``(stamp, p, theta)`` and raw
    frames whose header stamps are ``image_stamps`` (ns), whatever their recording times."""
    build = Messages("ros1")
    with Writer1(path) as w:
        info = w.add_connection(CAMERA_INFO_TOPIC, "sensor_msgs/msg/CameraInfo", typestore=build.ts)
        joints = w.add_connection(FIXTURE_TOPIC, "sensor_msgs/msg/JointState", typestore=build.ts)
        img = w.add_connection(IMAGE_TOPIC, "sensor_msgs/msg/Image", typestore=build.ts)
        w.write(info, 1, build.serialize(build.camera_info(1, rig.camera)))
        for k, (ns, p, theta) in enumerate(joint_rows):
            msg = build.joints(ns, p * rig.links.pin_pitch, theta)
            w.write(joints, 10 + k, build.serialize(msg))
        for k, ((_, _, _, rgb), ns) in enumerate(zip(frames, image_stamps, strict=True)):
            w.write(img, (k + 1) * 10**9, build.serialize(build.image(ns, rgb, "raw")))
    return path


def test_stamps_that_contradict_the_recording_are_named(tmp_path, frames, rig):
    """Image stamps reversed against the recording had assigned every frame another pose's joint
    state (278 mm median pose error), and two joint states at one stamp with different positions
    errors up to 177 mm (issue 51)."""
    joints = [(10**9 - 1, 0, 0.0), (2 * 10**9 - 1, 7, 0.0), (3 * 10**9 - 1, 14, 0.0)]
    fine = _lying_bag(tmp_path / "fine.bag", rig, frames[:3], [10**9, 2 * 10**9, 3 * 10**9], joints)
    assert bag_to_capture(fine, tmp_path / "c0", rig).frames == 3
    reversed_ = _lying_bag(
        tmp_path / "rev.bag", rig, frames[:3], [3 * 10**9, 2 * 10**9, 10**9], joints
    )
    with pytest.raises(
        ConfigError,
        match=rf"topic {IMAGE_TOPIC}: message 2: header.stamp: 2000000000 ns is earlier than "
        r"message 1's 3000000000 ns",
    ):
        bag_to_capture(reversed_, tmp_path / "c1", rig)
    twice = joints[:1] + [(10**9 - 1, 7, 0.0)] + joints[2:]
    double = _lying_bag(tmp_path / "dbl.bag", rig, frames[:3], [10**9, 2 * 10**9, 3 * 10**9], twice)
    with pytest.raises(
        ConfigError,
        match=rf"topic {FIXTURE_TOPIC}: message 2: position: \(p=7, theta=0 deg\) at the stamp "
        r"of message 1, which claims \(p=0, theta=0 deg\)",
    ):
        bag_to_capture(double, tmp_path / "c2", rig)


def _one_frame_bag(path: Path, rig, msg, compressed: bool = False) -> Path:
    """A ROS 1 bag with a CameraInfo and the one frame message ``msg``."""
    build = Messages("ros1")
    kind = "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image"
    with Writer1(path) as w:
        info = w.add_connection(CAMERA_INFO_TOPIC, "sensor_msgs/msg/CameraInfo", typestore=build.ts)
        img = w.add_connection(IMAGE_TOPIC, kind, typestore=build.ts)
        w.write(info, 10**9, build.serialize(build.camera_info(10**9, rig.camera)))
        w.write(img, 10**9, build.serialize(msg))
    return path


def test_encodings_that_lie_about_their_data_are_named(tmp_path, frames, rig):
    """Labels that do not describe the data had been read as garbage frames with 0 detections
    and exit 0; 16-bit frames had been scaled by 255/65535 in bags while capture folders refuse
    16-bit PNGs (issue 51)."""
    import dataclasses

    build = Messages("ros1")
    rgb = frames[0][3]
    bgr8 = build.image(10**9, rgb, "raw")
    good = write_ranges(tmp_path / "g.csv", [(0, 2 * 10**9, 0, "0.0")])
    where = rf"topic {IMAGE_TOPIC}: message 1"
    cases = {
        "mono8": rf"{where}: data: {rgb.size} bytes, expected step x rows = {rgb.shape[1]} x ",
        "yuv422": rf"{where}: data: {rgb.size} bytes, expected",
        "mono16": rf"{where}: encoding: 'mono16' is 16-bit; simgap reads 8-bit frames",
        "32FC1": rf"{where}: encoding: expected an 8-bit encoding .* got '32FC1'",
    }
    for k, (encoding, message) in enumerate(cases.items()):
        step = {"mono8": rgb.shape[1], "yuv422": 2 * rgb.shape[1]}.get(encoding, bgr8.step)
        lie = dataclasses.replace(bgr8, encoding=encoding, step=step)
        bag = _one_frame_bag(tmp_path / f"{k}.bag", rig, lie)
        with pytest.raises(ConfigError, match=message):
            bag_to_capture(bag, tmp_path / f"c{k}", rig, good)
    # rows padded to a 64-byte step are legitimate: read as the unpadded frame
    step = -(-bgr8.step // 64) * 64
    padded = np.zeros((rgb.shape[0], step), np.uint8)
    padded[:, : bgr8.step] = np.asarray(bgr8.data).reshape(rgb.shape[0], -1)
    msg = dataclasses.replace(bgr8, step=step, data=padded.reshape(-1))
    plain = _one_frame_bag(tmp_path / "p.bag", rig, bgr8)
    wide = _one_frame_bag(tmp_path / "w.bag", rig, msg)
    plain = bag_to_capture(plain, tmp_path / "cp", rig, good)
    wide = bag_to_capture(wide, tmp_path / "cw", rig, good)
    assert plain.frames == wide.frames == 1
    names = [sorted((tmp_path / c / "images").iterdir()) for c in ("cp", "cw")]
    assert names[0][0].read_bytes() == names[1][0].read_bytes()
    # a 16-bit PNG in a CompressedImage, named with its topic and message
    ok, png16 = cv2.imencode(".png", (rgb.astype(np.uint16) * 257))
    deep = build.image(10**9, (png16.tobytes(), "png"), "png")
    bag = _one_frame_bag(tmp_path / "d.bag", rig, deep, compressed=True)
    with pytest.raises(ConfigError, match=rf"{where}: data: a 16-bit PNG"):
        bag_to_capture(bag, tmp_path / "cd", rig, good)


def test_a_damaged_bag_is_a_named_error(tmp_path, png_capture, rig):
    """Corrupt database pages of a ROS 2 bag had surfaced as "CorruptError: database disk image
    is malformed" (issue 51): named, with the bag, topic and message where the reader failed."""
    bag = capture_to_bag(png_capture, tmp_path / "b2", "ros2")
    db = next(bag.glob("*.db3"))
    data = bytearray(db.read_bytes())
    rng = np.random.default_rng(0)
    start = len(data) // 2
    data[start : start + 3000] = rng.integers(0, 256, 3000, dtype=np.uint8).tobytes()
    db.write_bytes(bytes(data))
    # the image topic's message whose page the corruption hit (messages 1-3 at 30-70 % of the file)
    where = rf"^{bag}: topic \S+: message \d+"
    with pytest.raises(ConfigError, match=rf"{where}: cannot be read, the bag is damaged \("):
        ingest_bag(bag)


def test_exported_frames_raw_png_and_jpeg(tmp_path, smoke_variants_nc, session_cache):
    """`export-bag --images`: the smoke study's nine frames as raw, PNG and JPEG bags.

    Measured (OpenCV 5.0, 1920 x 1080 frames): raw 56.0 MB, PNG 0.59 MB (95x smaller) with the
    same ingested corners, errors and image statistics; JPEG (quality 80) ingests with every tag
    detected.
    """
    from simgap.results.dataset import read_netcdf

    sizes, data = {}, {}
    for images in ("raw", "png", "jpeg"):
        bag = tmp_path / f"{images}.bag"
        args = ["export-bag", "experiments/smoke.yaml", "-o", str(bag), "--images", images]
        res = CliRunner().invoke(app, [*args, "--cache", str(session_cache), "--no-progress"])
        assert res.exit_code == 0, res.output
        sizes[images] = bag.stat().st_size
        out = tmp_path / f"{images}.nc"
        res = CliRunner().invoke(app, ["ingest", str(bag), "-o", str(out), "--no-progress"])
        assert res.exit_code == 0, res.output
        data[images] = read_netcdf(out)
    assert sizes["raw"] >= 3 * sizes["png"]
    for name in ("corners", "error", "image_stats"):
        np.testing.assert_array_equal(data["png"][name].values, data["raw"][name].values)
    assert bool(data["jpeg"].detected.sum() == data["raw"].detected.sum())


def test_exported_mcap_carries_chunk_checksums(tmp_path, png_capture):
    """An MCAP simgap writes has each chunk's CRC-32 (rosbags' writer leaves 0), so a bag whose
    message bytes were damaged later is refused, naming the bag and topic, not read as data."""
    bag = capture_to_bag(png_capture, tmp_path / "one.mcap", "ros2", images="raw")
    data = bytearray(bag.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 8] = bytes(8)  # inside the raw frames' chunk
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    assert ingest_bag(bag).attrs["frames"] > 0
    with pytest.raises(ConfigError, match=r"damaged.mcap: topic .*Chunk checksum mismatch"):
        ingest_bag(damaged)
