"""Feed generated bad inputs to simgap's real loaders and count how each one is refused.

Six input families (issue 10): experiment YAML, calibration files, capture manifests, frame
images (with a 600 KB PNG of 25000 x 25000 px, issue 26), result datasets and inputs that lie
(issue 51: captures and bags whose data contradicts itself, bombs their calibration vouches
for), plus command-line calls, and the output paths of every command that would destroy an
input, a capture's files or a device (issue 26, ``benchmarks/fuzz_outputs.py``: for these,
named also means the scenario's files are byte-identical afterwards and nothing was written).
Every input is invalid by construction. For each, the outcome is one of

- ``named``: simgap's own error (ConfigError / DatasetError) naming the offending file (for a frame,
  a recorded failure: CaptureWarning and ``frames_unreadable``); for a command-line call, exit code
  2 with one line and no traceback;
- ``raw``: any other exception (or a traceback / another exit code);
- ``accepted``: the loader returned normally: an invalid value was accepted silently.

Target: 100 % named, 0 raw, 0 accepted.

    python benchmarks/fuzz_inputs.py [--seed 0] [--examples 3]
"""

from __future__ import annotations

import argparse
import copy
import math
import random
import shutil
import tempfile
import time
import warnings
from collections import Counter, defaultdict
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, get_type_hints

import cv2
import numpy as np
import yaml

from simgap.core.config import ConfigError
from simgap.core.rig import CameraModel, load_rig
from simgap.effects import EFFECTS
from simgap.pipeline.capture import (
    CaptureWarning,
    calibration_to_yaml,
    ingest,
    read_calibration,
    read_capture,
    write_capture,
)
from simgap.pipeline.experiment import load_experiment
from simgap.results.contract import check_dataset
from simgap.results.dataset import build_dataset, read_netcdf, write_netcdf

from fuzz_outputs import (  # isort: skip  (beside this script)
    BIG_FRAME_TARGET_MB,
    OUTPUT_CASES,
    big_frame_peaks,
    big_png,
    jpeg_claiming,
    make_scenario,
    run_case,
)

NAN, INF = float("nan"), float("inf")
SMALL = CameraModel(64, 48, 60.0, 60.0, 31.5, 23.5)
BASE_EXPERIMENT = {"name": "fz", "configurations": {"p": [7], "theta_deg": [0, 30]}}


@dataclass
class Case:
    """One bad input: its family, a label, the call that loads it and the file it must name."""

    family: str
    label: str
    load: Callable[[], Any]
    names: str
    frame_failure: bool = False  # images: a recorded failure counts as named


def outcome(case: Case) -> tuple[str, str]:
    """Run one case: ``("named" | "raw" | "accepted", detail)``."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            out = case.load()
        except ConfigError as exc:
            if case.names in str(exc):
                return "named", str(exc)
            return "raw", f"ConfigError not naming {case.names}: {exc}"
        except Exception as exc:  # what the benchmark counts
            return "raw", f"{type(exc).__name__}: {exc}"
    if case.frame_failure:
        recorded = any(issubclass(w.category, CaptureWarning) for w in caught)
        if recorded and out.attrs.get("frames_unreadable", 0) >= 1:
            return "named", "recorded frame failure"
    if isinstance(out, tuple) and out and out[0] == "cli":
        return out[1], out[2]
    return "accepted", repr(out)[:160]


# --- experiment YAML --------------------------------------------------------------------------


def _set(data: dict, path: str, value: Any) -> dict:
    out = copy.deepcopy(data)
    node = out
    keys = path.split(".")
    for k in keys[:-1]:
        node = node.setdefault(k, {})
    node[keys[-1]] = value
    return out


def experiment_cases(tmp: Path, rng: random.Random) -> list[Case]:
    """Bad values at every kind of key, bad structure, bad parents."""
    values: dict[str, list[Any]] = {
        "render.spp": [0, -1, 1.5, "many", NAN, [4]],  # null: the render mode's default
        "render.sampler": ["sobol", 3],
        "render.margin_px": [0, 3, -24],
        "render.max_depth": [1, 0, NAN],
        "render.seed": ["x", 1.5],
        "image.exposure": [0, -1, NAN, INF, "bright"],
        "image.encoding": ["gamma22", None],
        "detector.dictionary": ["DICT_FOO", "ArucoDetector", "CORNER_REFINE_NONE", 5, ""],
        "detector.corner_refinement": ["FOO", 1],
        "detector.subpix_window_px": [0, -3],
        "detector.subpix_max_iterations": [0],
        "detector.subpix_min_accuracy_px": [0, -1, NAN, INF],
        "pnp.method": ["P3P", 0],
        "rig.camera.fx": [0, -1, NAN, INF, 1e-300, 1e300, "f"],
        "rig.camera.fy": [NAN, 1e-300, 1e300],
        "rig.camera.cx": [NAN, -5000, 1e9, INF],
        "rig.camera.cy": [NAN, -5000, 1e9],
        "rig.camera.width": [0, -5, 1e20, 1.5, NAN],
        "rig.camera.height": [0, 1e20],
        "rig.camera.distortion": [[NAN, 0, 0, 0, 0], [1e300, 0, 0, 0, 0], [0, 0, 5, 0, 0], [0]],
        "rig.links.pin_pitch": [0, -0.0254, NAN, INF],
        "rig.links.tag_height": [NAN, INF],
        "rig.links.eyepoint_to_carriage": [[NAN, 0, 0], [0, 0], [INF, 0, 0]],
        "rig.links.carriage_to_turntable": [[0, NAN, 0]],
        "rig.grid.p": [[], [1, 1], [-1], [NAN]],
        "rig.grid.theta_step_deg": [0, -10, NAN, INF],
        "rig.grid.theta_count": [0, 1e7, 1e12, -1, 72],
        "rig.tags.dictionary": ["DICT_FOO", "ArucoDetector", "CORNER_REFINE_NONE"],
        "rig.tags.size": [0, NAN, -0.02],
        "rig.tags.quiet_zone_cells": [-1],
        "rig.tags.faces": [[{"id": 0, "radius": 0.08}, {"id": 0, "radius": 0.04}]],
        "rig.visibility.min_view_angle_deg": [90, NAN, -1],
        "configurations.p": [[15], [7, 7], ["a"], [NAN]],
        "configurations.theta_deg": [[0, 360], [5], [NAN], [30, 30], [10, 370]],
        "configurations.tags": [[7], [0, 0]],
        "repeats": [0, -1, 1e12, 1.5, NAN],
        "scene.lights.key.position": [[NAN, 0, 0.4], [0, INF, 0.4]],
        "scene.lights.key.radiance": [-1, NAN],
        "scene.lights.key.cutoff_deg": [0, 90],
        "scene.materials.table.reflectance": [NAN, INF],
        "scene.integrator.max_depth": [NAN],
    }
    cases = []
    for key, bad in values.items():
        for value in bad:
            cases.append((f"{key}={value!r}", _set(BASE_EXPERIMENT, key, value)))
    # Detector extra: unknown names, wrong types, NaN, negative, OpenCV-refused values.
    for name, value in [
        ("readDetectorParameters", 1),
        ("noSuchParameter", 1),
        ("markerBorderBits", 1.5),
        ("minMarkerPerimeterRate", NAN),
        ("maxMarkerPerimeterRate", INF),
        ("adaptiveThreshWinSizeMin", 1),
        ("adaptiveThreshWinSizeStep", 0),
        ("errorCorrectionRate", -3),
        ("detectInvertedMarker", 2),
        ("cornerRefinementMethod", 17),
        ("perspectiveRemovePixelPerCell", 100000),
        ("minDistanceToBorder", -10),
    ]:
        cases.append(
            (f"extra.{name}={value!r}", _set(BASE_EXPERIMENT, "detector.extra", {name: value}))
        )
    # Effect parameters: NaN and infinity in every numeric parameter of every effect.
    for name, cls in sorted(EFFECTS.items()):
        hints = get_type_hints(cls.Params)
        for f in fields(cls.Params):
            if "float" in str(hints[f.name]) and "tuple" not in str(hints[f.name]):
                value = rng.choice([NAN, INF, -INF])
                cases.append(
                    (
                        f"effects.{name}.{f.name}={value}",
                        _set(BASE_EXPERIMENT, f"effects.{name}", {f.name: value}),
                    )
                )
    cases.append(
        ("calibration cx -1e9", _set(BASE_EXPERIMENT, "effects.calibration", {"cx": -1e9}))
    )
    cases.append(("grid duplicate values", _set(BASE_EXPERIMENT, "grid", {"exposure.ev": [1, 1]})))
    cases.append(("grid bad key", _set(BASE_EXPERIMENT, "grid", {"exposure": [1]})))
    cases.append(("grid bad value", _set(BASE_EXPERIMENT, "grid", {"blur.sigma_px": [NAN]})))
    cases.append(
        ("variant duplicate", _set(BASE_EXPERIMENT, "variants", [{"name": "a"}, {"name": "a"}]))
    )
    cases.append(
        (
            "variant unknown effect",
            _set(BASE_EXPERIMENT, "variants", [{"name": "a", "effects": {"nope": {}}}]),
        )
    )
    cases.append(("unknown top-level key", _set(BASE_EXPERIMENT, "bogus", 1)))

    out = []
    for i, (label, data) in enumerate(cases):
        path = tmp / f"exp{i}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        out.append(Case("experiment", label, lambda p=path: load_experiment(p), str(path)))
    raw_texts = {
        "empty": b"",
        "comment only": b"# nothing here\n",
        "non-UTF-8": b"name: caf\xe9\n",
        "non-UTF-8 (latin-1 comment)": b"# \xff\xfe\nname: x\n",
        "duplicate key": b"name: x\nrender: {spp: 4}\nrender: {spp: 8}\n",
        "nested duplicate key": b"name: x\nrender:\n  spp: 4\n  spp: 8\n",
        "invalid YAML": b"name: x\nrender: [1, 2\n",
        "tabs": b"name: x\n\trender: 1\n",
        "top-level list": b"- a\n- b\n",
        "top-level scalar": b"42\n",
        "bad timestamp": b"name: 2024-13-45\n",
        "python tag": b"name: !!python/object:os.system x\n",
        "exponent repeats": b"name: x\nrepeats: 1e12\n",
        "exponent theta_count": b"name: x\nrig: {grid: {theta_count: 1e7}}\n",
        "binary junk": bytes(rng.randrange(256) for _ in range(200)),
        "NUL bytes": b"name: x\x00\x00\n",
        "source key": b"name: x\nsource: y\n",
        "inherit not a path": b"name: x\ninherit: [a]\n",
        "inherit missing": b"name: x\ninherit: nowhere.yaml\n",
    }
    for i, (label, text) in enumerate(raw_texts.items()):
        path = tmp / f"raw{i}.yaml"
        path.write_bytes(text)
        out.append(Case("experiment", label, lambda p=path: load_experiment(p), str(path)))
    # Errors inside an inherited parent must name the parent.
    parents = {
        "parent spp 0": b"name: p\nrender: {spp: 0}\n",
        "parent non-UTF-8": b"name: p\ndescription: \xff\n",
        "parent empty": b"",
        "parent duplicate key": b"name: p\nimage: {exposure: 1}\nimage: {exposure: 2}\n",
        "parent NaN exposure": b"name: p\nimage: {exposure: .nan}\n",
        "parent bad dictionary": b"name: p\ndetector: {dictionary: ArucoDetector}\n",
        "parent theta 0 and 360": b"name: p\nconfigurations: {theta_deg: [0, 360]}\n",
        "parent repeats 1e12": b"name: p\nrepeats: 1e12\n",
    }
    for i, (label, text) in enumerate(parents.items()):
        parent = tmp / f"parent{i}.yaml"
        parent.write_bytes(text)
        child = tmp / f"child{i}.yaml"
        child.write_text(f"name: c\ninherit: {parent.name}\nrender: {{seed: 1}}\n")
        out.append(Case("experiment", label, lambda p=child: load_experiment(p), str(parent)))
    loop = tmp / "loop.yaml"
    loop.write_text("name: l\ninherit: loop2.yaml\n")
    (tmp / "loop2.yaml").write_text("name: l2\ninherit: loop.yaml\n")
    out.append(Case("experiment", "circular inherit", lambda: load_experiment(loop), str(loop)))
    return out


# --- calibration files ------------------------------------------------------------------------


def calibration_cases(tmp: Path, rng: random.Random) -> list[Case]:
    """ROS and OpenCV FileStorage files with bad values, bad structure and truncation."""
    rig_cam = load_rig().camera
    ros = yaml.safe_load(calibration_to_yaml(rig_cam, "ros"))
    texts: dict[str, bytes] = {}

    def ros_with(label: str, **changes: Any) -> None:
        data = copy.deepcopy(ros)
        for key, value in changes.items():
            if key in ("fx", "cx", "fy", "cy", "skew"):
                i = {"fx": 0, "skew": 1, "cx": 2, "fy": 4, "cy": 5}[key]
                data["camera_matrix"]["data"][i] = value
            elif key.startswith("k"):
                data["distortion_coefficients"]["data"][int(key[1:])] = value
            elif value is None:
                data.pop(key)
            else:
                data[key] = value
        texts[f"ros {label}"] = yaml.safe_dump(data, sort_keys=False).encode()

    for v in (NAN, INF, -INF, 0.0, -1386.0, 1e-300, 1e300, 50.0, 1e6):
        ros_with(f"fx={v}", fx=v)
    for v in (NAN, INF, -INF, -1386.0, -1e5, 1e300, 1e6):
        ros_with(f"cy={v}", cy=v)
    for v in (NAN, INF, -5000.0, 1e9, 3000.0):
        ros_with(f"cx={v}", cx=v)
        ros_with(f"fy={v}", fy=v if math.isnan(v) or math.isinf(v) else 1e-9)
    for i in range(5):
        ros_with(f"k{i}=1e300", **{f"k{i}": 1e300})
        ros_with(f"k{i}=nan", **{f"k{i}": NAN})
    for v in (0, -1, 1e20, 1.5, "wide", 70000):
        ros_with(f"image_width={v}", image_width=v)
        ros_with(f"image_height={v}", image_height=v)
    ros_with("skew", skew=3.0)
    ros_with("unknown model", distortion_model="ocam")
    ros_with("fisheye with a 5th coefficient", distortion_model="equidistant", k4=0.1)
    ros_with("no camera_matrix", camera_matrix=None)
    ros_with("no distortion", distortion_coefficients=None)
    ros_with("camera_matrix list", camera_matrix=[1, 2, 3])
    ros_with("camera_matrix 8", camera_matrix={"rows": 3, "cols": 3, "data": [1.0] * 8})
    ros_with("camera_matrix strings", camera_matrix={"rows": 3, "cols": 3, "data": ["a"] * 9})
    ros_with("rows 4", camera_matrix={"rows": 4, "cols": 3, "data": ros["camera_matrix"]["data"]})
    ros_with("k4 nonzero", distortion_coefficients={"data": [0, 0, 0, 0, 0, 0.1]})
    ros_with(
        "distortion rows x cols", distortion_coefficients={"rows": 2, "cols": 2, "data": [0] * 5}
    )
    ros_text = calibration_to_yaml(rig_cam, "ros")
    texts["ros duplicate key"] = (ros_text + "image_width: 1280\n").encode()
    texts["ros non-UTF-8"] = ros_text.encode().replace(b"simgap", b"sim\xe9gap")
    texts["ros list"] = b"- 1\n- 2\n"
    texts["empty"] = b""
    texts["binary junk"] = bytes(rng.randrange(256) for _ in range(300))
    cm_end = ros_text.index("distortion_model")  # cut inside the camera matrix: info is lost
    start = ros_text.index("camera_matrix")
    last = ros_text.rindex("- ", start, cm_end)
    for cut in sorted(rng.sample(range(start, last), 6)):
        texts[f"ros truncated at {cut}"] = ros_text[:cut].encode()
    ocv = calibration_to_yaml(rig_cam, "opencv")
    cm = ocv.index("camera_matrix")
    cm_last = ocv.index("]", cm)
    for cut in sorted(rng.sample(range(cm, cm_last), 8)):
        texts[f"opencv truncated at {cut}"] = ocv[:cut].encode()
    for old, new, label in [
        ("1386.", ".nan", "fx nan"),
        ("1386.", "1.e-300", "fx 1e-300"),
        ("959.5", "-5000.", "cx -5000"),
        ("1920", "100000000000000000000", "width 1e20"),
        ("image_width: 1920", "image_width: abc", "width string"),
        ("camera_matrix", "camera_matrixx", "no camera matrix"),
        ("rows: 3", "rows: 4", "rows 4"),
        ("distortion_model: plumb_bob", "distortion_model: ocam", "unknown model"),
    ]:
        texts[f"opencv {label}"] = ocv.replace(old, new, 1).encode()
    texts["opencv garbage after header"] = b"%YAML:1.0\n---\n{{{{ ::: [[[\n"
    texts["opencv only header"] = b"%YAML:1.0\n"
    out = []
    for i, (label, data) in enumerate(texts.items()):
        path = tmp / f"camera{i}.yaml"
        path.write_bytes(data)
        out.append(Case("calibration", label, lambda p=path: read_calibration(p), str(path)))
    return out


# --- capture folders: manifests and images ----------------------------------------------------


def _capture(folder: Path, image_format: str = "png") -> Path:
    """A valid two-frame capture of blank 64x48 frames."""
    img = np.full((SMALL.height, SMALL.width, 3), 200, np.uint8)
    frames = [(0, 0.0, 0, img), (7, math.radians(30), 0, img)]
    write_capture(folder, frames, SMALL, image_format=image_format)
    return folder


def manifest_cases(tmp: Path, rng: random.Random) -> list[Case]:
    """Manifests with bad columns, values, rows, paths leaving the folder and CSV errors."""
    rig = load_rig()
    header = "image,p,theta_rad"
    good = "images/p00_t000.png"
    outside = tmp / "outside.png"
    outside.write_bytes((tmp / "seed" / "images" / "p00_t000.png").read_bytes())
    rows = {
        "no header": "",
        "unknown column": f"{header},exposure\n{good},0,0,1\n",
        "missing column": f"image,p\n{good},0\n",
        "duplicate column": f"{header},p\n{good},0,0,0\n",
        "no rows": f"{header}\n",
        "p 15": f"{header}\n{good},15,0\n",
        "p -1": f"{header}\n{good},-1,0\n",
        "p text": f"{header}\n{good},a,0\n",
        "p 1.5": f"{header}\n{good},1.5,0\n",
        "p nan": f"{header}\n{good},nan,0\n",
        "p 1e300": f"{header}\n{good},1e300,0\n",
        "theta nan": f"{header}\n{good},0,nan\n",
        "theta inf": f"{header}\n{good},0,inf\n",
        "theta off-stop": f"{header}\n{good},0,0.1\n",
        "theta text": f"{header}\n{good},0,zero\n",
        "theta 1e300": f"{header}\n{good},0,1e300\n",
        "theta empty": f"{header}\n{good},0,\n",
        "repeat -1": f"{header},repeat\n{good},0,0,-1\n",
        "repeat 1.5": f"{header},repeat\n{good},0,0,1.5\n",
        "repeat text": f"{header},repeat\n{good},0,0,x\n",
        "duplicate row": f"{header}\n{good},0,0\n{good},0,6.283185307\n",
        "too many fields": f"{header}\n{good},0,0,9\n",
        "too few fields": f"{header}\n{good},0\n",
        "empty image": f"{header}\n,0,0\n",
        "missing image": f"{header}\nimages/none.png,0,0\n",
        "image is a folder": f"{header}\nimages,0,0\n",
        "absolute /etc/passwd": f"{header}\n/etc/passwd,0,0\n",
        "absolute /etc/hostname": f"{header}\n/etc/hostname,0,0\n",
        "absolute to a real frame": f"{header}\n{outside},0,0\n",
        "dot-dot": f"{header}\n../outside.png,0,0\n",
        "dot-dot deep": f"{header}\nimages/../../../../../../etc/passwd,0,0\n",
        "dot-dot inside": f"{header}\nimages/../images/p00_t000.png,0,0\n",
        "NUL in path": f"{header}\nimages/p00\x00.png,0,0\n",
        "field over the CSV limit": f"{header}\n{'x' * 200_000},0,0\n",
        "unterminated quote": f'{header}\n"{good},0,0\n',
        "device file": f"{header}\n/dev/zero,0,0\n",
        "proc file": f"{header}\n/proc/self/environ,0,0\n",
    }
    for k in range(8):  # random junk rows
        junk = "".join(rng.choice("abc,;\"'\n\t0123456789.-") for _ in range(40))
        rows[f"junk {k}"] = f"{header}\n{junk}\n"
    for _ in range(6):  # random off-stop angles
        theta = rng.uniform(0.002, 0.17)
        rows[f"theta {theta:.4f}"] = f"{header}\n{good},0,{theta}\n"
    out = []
    for i, (label, text) in enumerate(rows.items()):
        folder = _capture(tmp / f"m{i}")
        manifest = folder / "manifest.csv"
        manifest.write_text(text)
        out.append(Case("manifest", label, lambda f=folder: read_capture(f, rig), str(manifest)))
    for i, target in enumerate(["/etc/passwd", str(outside), "/dev/zero"]):
        folder = _capture(tmp / f"link{i}")
        (folder / "images" / "link.png").symlink_to(target)
        (folder / "manifest.csv").write_text(f"{header}\nimages/link.png,0,0\n")
        out.append(
            Case(
                "manifest",
                f"symlink to {target}",
                lambda f=folder: read_capture(f, rig),
                str(folder),
            )
        )
    folder = _capture(tmp / "linkdir")
    (folder / "images" / "up").symlink_to(tmp)
    (folder / "manifest.csv").write_text(f"{header}\nimages/up/outside.png,0,0\n")
    out.append(
        Case("manifest", "symlinked folder out", lambda f=folder: read_capture(f, rig), str(folder))
    )
    folder = _capture(tmp / "latin1")
    (folder / "manifest.csv").write_bytes(
        f"{header}\nimages/p00_t000.png,0,0 \xe9\n".encode("latin-1")
    )
    out.append(Case("manifest", "non-UTF-8", lambda f=folder: read_capture(f, rig), str(folder)))
    return out


def _lying_bag(
    path: Path, frames: list[tuple[int, Any]], joints, info: CameraModel = SMALL
) -> Path:
    """A ROS 1 bag recorded at 1 s steps: a CameraInfo of ``info``, joint states ``(stamp, p,
    theta)`` and raw or compressed frames ``(header stamp, message)``."""
    from rosbags.rosbag1 import Writer

    from simgap.pipeline.bag import CAMERA_INFO_TOPIC, FIXTURE_TOPIC, IMAGE_TOPIC
    from simgap.pipeline.bag.messages import Messages

    build = Messages("ros1")
    kind = type(frames[0][1]).__name__.split("__")[-1]
    with Writer(path) as w:
        c = w.add_connection(CAMERA_INFO_TOPIC, "sensor_msgs/msg/CameraInfo", typestore=build.ts)
        j = w.add_connection(FIXTURE_TOPIC, "sensor_msgs/msg/JointState", typestore=build.ts)
        i = w.add_connection(IMAGE_TOPIC, f"sensor_msgs/msg/{kind}", typestore=build.ts)
        w.write(c, 1, build.serialize(build.camera_info(1, info)))
        rig = load_rig()
        for k, (ns, p, theta) in enumerate(joints):
            w.write(j, 10 + k, build.serialize(build.joints(ns, p * rig.links.pin_pitch, theta)))
        for k, (_, msg) in enumerate(frames):
            w.write(i, (k + 1) * 10**9, build.serialize(msg))
    return path


def lying_cases(tmp: Path, rng: random.Random) -> list[Case]:
    """Inputs whose data contradicts itself (issue 51): captures and bags that lie."""
    import dataclasses

    from simgap.pipeline.bag import bag_to_capture
    from simgap.pipeline.bag.messages import Messages

    rig = load_rig()
    out = []
    header = "image,p,theta_rad"
    folder = _capture(tmp / "lie_same_file")
    (folder / "manifest.csv").write_text(
        f"{header}\nimages/p00_t000.png,0,0\nimages/p00_t000.png,7,0\n"
    )
    out.append(Case("lying", "one image for two poses", lambda f=folder: read_capture(f, rig),
                    str(folder / "manifest.csv")))  # fmt: skip
    folder = _capture(tmp / "lie_manifest_link")
    secret = tmp / "secret.txt"
    secret.write_text("password=hunter2\n")
    (folder / "manifest.csv").unlink()
    (folder / "manifest.csv").symlink_to(secret)
    out.append(Case("lying", "manifest linked out", lambda f=folder: read_capture(f, rig),
                    str(folder / "manifest.csv")))  # fmt: skip
    folder = _capture(tmp / "lie_vouched")
    vouching = CameraModel(25000, 25000, 20000.0, 20000.0, 12499.5, 12499.5)
    (folder / "camera.yaml").write_text(calibration_to_yaml(vouching))
    big_png(folder / "images" / "p00_t000.png")
    out.append(Case("lying", "calibration vouching for a bomb", lambda f=folder: ingest(f),
                    str(folder / "camera.yaml")))  # fmt: skip
    build = Messages("ros1")
    img = np.full((SMALL.height, SMALL.width, 3), 200, np.uint8)
    joints = [(10**9 - 1, 0, 0.0), (2 * 10**9 - 1, 7, 0.0)]
    stamped = [(ns, build.image(ns, img, "raw")) for ns in (10**9, 2 * 10**9)]
    bags = {
        "image stamps reversed": (
            [(ns, build.image(ns, img, "raw")) for ns in (2 * 10**9, 10**9)], joints, SMALL
        ),
        "two joint states at one stamp": (stamped, [joints[0], (joints[0][0], 7, 0.0)], SMALL),
        "mono8 label on bgr8 data": (
            [(ns, dataclasses.replace(m, encoding="mono8", step=SMALL.width)) for ns, m in stamped],
            joints, SMALL,
        ),
        "yuv422 label on bgr8 data": (
            [(ns, dataclasses.replace(m, encoding="yuv422", step=2 * SMALL.width))
             for ns, m in stamped], joints, SMALL,
        ),
        "mono16 frames": (
            [(ns, dataclasses.replace(m, encoding="mono16", step=2 * SMALL.width,
                                      data=np.asarray(m.data)[: 2 * SMALL.width * SMALL.height]))
             for ns, m in stamped], joints, SMALL,
        ),
        "CameraInfo vouching for a bomb": (
            [(ns, build.image(ns, (big_png(tmp / "bomb.png").read_bytes(), "png"), "png"))
             for ns in (10**9, 2 * 10**9)], joints, vouching,
        ),
    }  # fmt: skip
    for k, (label, (frames, joint_rows, info)) in enumerate(bags.items()):
        bag = _lying_bag(tmp / f"lie{k}.bag", frames, joint_rows, info)
        out.append(Case("lying", label, lambda b=bag, k=k: bag_to_capture(b, tmp / f"lc{k}", rig),
                        str(bag)))  # fmt: skip
    return out


def damaged_bag_cases(tmp: Path, rng: random.Random) -> list[Case]:
    """Bags damaged after they were written (issue 51's reader errors): cut short, zeroed,
    bytes flipped, a ROS 2 folder's metadata removed, garbled or naming an unknown type."""
    from simgap.pipeline.bag import bag_to_capture, capture_to_bag

    rig = load_rig()
    source = _capture(tmp / "damage_source")
    out = []

    def case(label: str, bag: Path) -> None:
        k = len(out)
        out.append(Case("damaged", label, lambda b=bag, k=k: bag_to_capture(b, tmp / f"dc{k}", rig),
                        str(bag)))  # fmt: skip

    for name, fmt, images in (("one.bag", "ros1", "raw"), ("one.db3", "ros2", "png"),
                              ("one.mcap", "ros2", "raw")):  # fmt: skip
        good = capture_to_bag(source, tmp / f"good_{name}", fmt, rig, images)
        data = good.read_bytes()
        n = len(data)
        damages = {
            "cut to 25 %": data[: n // 4],
            "cut to 50 %": data[: n // 2],
            "cut to 90 %": data[: 9 * n // 10],
            "a tenth zeroed": data[: n // 2] + bytes(n // 10) + data[n // 2 + n // 10 :],
        }
        flipped = bytearray(data)
        for i in rng.sample(range(n // 8, n), 16):
            flipped[i] ^= 0xFF
        damages["16 bytes flipped"] = bytes(flipped)
        for label, damaged in damages.items():
            bag = tmp / f"damaged_{label.replace(' ', '_').replace('%', 'pct')}_{name}"
            bag.write_bytes(damaged)
            case(f"{name}: {label}", bag)
    folder = capture_to_bag(source, tmp / "good_folder", "ros2", rig, "png")
    for label, change in {
        "metadata.yaml removed": lambda m: m.unlink(),
        "metadata.yaml garbled": lambda m: m.write_text("rosbag2_bagfile_information: [\n"),
        "an unknown message type": lambda m: m.write_text(
            m.read_text().replace("sensor_msgs/msg/CompressedImage", "acme_msgs/msg/Frame")
        ),
    }.items():
        bag = tmp / f"damaged_folder_{len(out)}"
        shutil.copytree(folder, bag)
        change(bag / "metadata.yaml")
        case(f"ROS 2 folder: {label}", bag)
    return out


def image_cases(tmp: Path, rng: random.Random) -> list[Case]:
    """Frames that are truncated, not images, 16-bit or of the wrong size."""
    rig = load_rig()
    out = []
    for fmt in ("png", "jpg"):
        seed = _capture(tmp / f"seed-{fmt}", fmt)
        data = (seed / "images" / f"p07_t030.{fmt}").read_bytes()
        for cut in sorted(rng.sample(range(1, len(data) - 1), 8)):
            out.append((f"{fmt} truncated to {cut}/{len(data)} B", fmt, data[:cut]))
        out.append((f"{fmt} zero bytes", fmt, b""))
        out.append((f"{fmt} text", fmt, b"not an image\n"))
        out.append((f"{fmt} random bytes", fmt, bytes(rng.randrange(256) for _ in range(500))))
    ok, big = cv2.imencode(".png", np.full((96, 128, 3), 200, np.uint8))
    out.append(("png of the wrong size", "png", big.tobytes()))
    ok, sixteen = cv2.imencode(".png", np.full((48, 64, 3), 40000, np.uint16))
    out.append(("16-bit png", "png", sixteen.tobytes()))
    out.append(("png of 25000x25000 px (600 KB)", "png", big_png(tmp / "big.png").read_bytes()))
    out.append(("jpg whose header says 25000x25000 px", "jpg", jpeg_claiming(25000, 25000)))
    ok, sixteen_gray = cv2.imencode(".png", np.full((48, 64), 1000, np.uint16))
    out.append(("16-bit grey png", "png", sixteen_gray.tobytes()))
    cases = []
    for i, (label, fmt, data) in enumerate(out):
        folder = _capture(tmp / f"i{i}", fmt)
        bad = folder / "images" / f"p07_t030.{fmt}"  # the second frame: the first stays good
        bad.write_bytes(data)
        cases.append(
            Case("images", label, lambda f=folder: ingest(f, rig), str(bad), frame_failure=True)
        )
    folder = _capture(tmp / "unsized", "png")  # an OpenCV camera.yaml without the image size
    long_lens = CameraModel(64, 48, 1386.0, 1386.0, 31.5, 23.5)  # plausible at 25000 px too
    cal = calibration_to_yaml(long_lens, "opencv").replace("image_width: 64\n", "")
    (folder / "camera.yaml").write_text(cal.replace("image_height: 48\n", ""))
    (folder / "images" / "p00_t000.png").write_bytes((tmp / "big.png").read_bytes())
    label = "png of 25000x25000 px, camera.yaml without a size"
    cases.append(Case("images", label, lambda: ingest(folder, rig), str(folder / "camera.yaml")))
    return cases


# --- datasets ---------------------------------------------------------------------------------


def _dataset():
    rig = load_rig()
    tags, ps, thetas = (0, 1), (0, 7), np.deg2rad([0.0, 30.0, 180.0])
    shape = (len(tags), len(ps), len(thetas))
    expected = np.array(
        [[[rig.expected_pose(t, p, th) for th in thetas] for p in ps] for t in tags]
    )
    visible = np.array([[[rig.is_visible(t, p, th) for th in thetas] for p in ps] for t in tags])
    full = (1, 1) + shape
    rng = np.random.default_rng(0)
    error = rng.normal(0, 0.002, full + (6,))
    results = {
        "detected": visible[None, None].copy(),
        "estimated": expected[None, None] + error,
        "error": error,
        "reproj_px": rng.uniform(0.01, 0.3, full),
        "corners": rng.uniform(0, 1000, full + (4, 2)),
    }
    return build_dataset(tags, ps, thetas, expected, visible, results)


def dataset_cases(tmp: Path, rng: random.Random) -> list[Case]:
    """Datasets that break the contract, and files that are not datasets."""
    base = _dataset()
    muts: dict[str, Callable[[Any], Any]] = {}
    for name in ("error", "detected", "visible"):
        muts[f"no {name}"] = lambda d, n=name: d.drop_vars(n)
    for name in ("p", "theta", "tag", "variant", "repeat", "axis"):
        muts[f"no coord {name}"] = lambda d, n=name: d.drop_vars(n)
    muts["p strings"] = lambda d: d.assign_coords(p=[str(v) for v in d.p.values])
    muts["p floats"] = lambda d: d.assign_coords(p=d.p.values + 0.5)
    muts["tag strings"] = lambda d: d.assign_coords(tag=["a", "b"])
    muts["tag floats"] = lambda d: d.assign_coords(tag=[0.0, 1.5])
    muts["repeat floats"] = lambda d: d.assign_coords(repeat=[0.5])
    muts["repeat strings"] = lambda d: d.assign_coords(repeat=["r0"])
    muts["variant integer"] = lambda d: d.assign_coords(variant=[0])
    muts["variant float"] = lambda d: d.assign_coords(variant=[1.5])
    muts["axis integers"] = lambda d: d.assign_coords(axis=np.arange(6))
    muts["axis renamed"] = lambda d: d.assign_coords(axis=["x", "y", "z", "a", "b", "c"])
    muts["theta degrees"] = lambda d: d.assign_coords(theta=np.rad2deg(d.theta.values))
    muts["theta negative"] = lambda d: d.assign_coords(theta=d.theta.values - 1.0)
    muts["theta nan"] = lambda d: d.assign_coords(theta=[0.0, np.nan, 1.0])
    muts["theta strings"] = lambda d: d.assign_coords(theta=["0", "30", "180"])
    muts["theta integers"] = lambda d: d.assign_coords(theta=[0, 30, 180])
    muts["theta 7 rad"] = lambda d: d.assign_coords(theta=[0.0, 1.0, 7.0])
    muts["theta duplicate"] = lambda d: d.assign_coords(theta=[0.0, 0.5, 0.5])
    muts["p duplicate"] = lambda d: d.assign_coords(p=[7, 7])
    for _ in range(4):
        scale = rng.uniform(3.0, 100.0)
        muts[f"theta x {scale:.1f}"] = lambda d, s=scale: d.assign_coords(theta=d.theta.values * s)
    for name in ("error", "estimated", "expected", "reproj_px", "corners"):
        muts[f"{name} strings"] = lambda d, n=name: d.assign({n: d[n].astype(str)})
    for name in ("visible", "detected"):
        muts[f"{name} strings"] = lambda d, n=name: d.assign({n: d[n].astype(str)})
        muts[f"{name} 0.5"] = lambda d, n=name: d.assign({n: d[n].astype(float) * 0.5})
        muts[f"{name} 2"] = lambda d, n=name: d.assign({n: d[n].astype(int) * 2})
    muts["error transposed"] = lambda d: d.assign(error=d.error.transpose("axis", ...))
    muts["detected transposed"] = lambda d: d.assign(detected=d.detected.transpose("theta", ...))
    muts["error without axis"] = lambda d: d.assign(error=d.error.isel(axis=0))
    muts["visible with repeat"] = lambda d: d.assign(visible=d.detected.isel(variant=0))
    muts["calibration_yaml garbage"] = lambda d: d.assign_attrs(calibration_yaml="[[[")
    muts["calibration_yaml list"] = lambda d: d.assign_attrs(calibration_yaml="- 1\n")
    muts["calibration_yaml fx nan"] = lambda d: d.assign_attrs(
        calibration_yaml="width: 1920\nheight: 1080\nfx: .nan\nfy: 1386\ncx: 959.5\ncy: 539.5\n"
        "distortion: [0, 0, 0, 0, 0]\n"
    )
    muts["calibration_yaml cx -5000"] = lambda d: d.assign_attrs(
        calibration_yaml="width: 1920\nheight: 1080\nfx: 1386\nfy: 1386\ncx: -5000\ncy: 539.5\n"
        "distortion: [0, 0, 0, 0, 0]\n"
    )
    out = []
    for i, (label, mutate) in enumerate(muts.items()):
        path = tmp / f"ds{i}.nc"
        try:
            write_netcdf(mutate(base), path)
        except Exception as exc:  # netCDF cannot store this mutation: not generated
            print(f"(skipped dataset mutation {label!r}: {type(exc).__name__})")
            continue
        out.append(
            Case("datasets", label, lambda p=path: check_dataset(read_netcdf(p), p), str(path))
        )
    good = tmp / "good.nc"
    write_netcdf(base, good)
    data = good.read_bytes()
    files = {
        "junk": b"this is not a netCDF file\n",
        "empty": b"",
        "random bytes": bytes(rng.randrange(256) for _ in range(4096)),
        "json": b'{"p": [0, 7]}',
        "PNG": (tmp / "seed" / "images" / "p00_t000.png").read_bytes(),
    }
    for cut in sorted(rng.sample(range(8, len(data) // 2), 6)):
        files[f"truncated to {cut}/{len(data)} B"] = data[:cut]
    for i, (label, content) in enumerate(files.items()):
        path = tmp / f"file{i}.nc"
        path.write_bytes(content)
        out.append(
            Case(
                "datasets",
                f"file: {label}",
                lambda p=path: check_dataset(read_netcdf(p), p),
                str(path),
            )
        )
    diag = tmp / "nocorners.nc"
    write_netcdf(base.drop_vars("corners"), diag)

    def diagnose_without_corners(p: Path = diag) -> Any:
        from simgap.diagnosis.diagnose import diagnose

        return diagnose(read_netcdf(p), None, tmp / "cache")  # fails before simulating

    out.append(Case("datasets", "diagnose: no corners", diagnose_without_corners, "nocorners.nc"))
    nodiag = tmp / "noerror.nc"
    write_netcdf(base.drop_vars("error"), nodiag)
    out.append(
        Case(
            "datasets",
            "diagnose: no error",
            lambda p=nodiag: diagnose_without_corners(p),
            "noerror.nc",
        )
    )
    return out


# --- command line ------------------------------------------------------------------------------


def cli_cases(tmp: Path, sources: dict[str, list[Case]]) -> list[Case]:
    """Command-line calls on a sample of the bad inputs: exit code 2, one line, no traceback."""
    from typer.testing import CliRunner

    from simgap.cli import app

    runner = CliRunner()

    def call(args: list[str]) -> tuple[str, str, str]:
        res = runner.invoke(app, args)
        lines = [line for line in res.output.splitlines() if line.strip()]
        text = res.output.strip()
        if res.exit_code == 2 and len(lines) == 1 and "Traceback" not in text:
            return ("cli", "named", text)
        if res.exit_code == 0:
            return ("cli", "accepted", text[:160])
        return ("cli", "raw", f"exit {res.exit_code}: {text[-300:]}")

    out = []
    for case in sources["experiment"][::12]:
        out.append(
            Case(
                "cli",
                f"run {case.label}",
                lambda c=case: call(["run", c.names, "-o", str(tmp / "o.nc")]),
                "",
            )
        )
    for case in sources["datasets"][::8]:
        for cmd in ("report", "compare"):
            out.append(
                Case(
                    "cli",
                    f"{cmd} {case.label}",
                    lambda c=case, m=cmd: call([m, c.names, "-o", str(tmp / "rep")]),
                    "",
                )
            )
    for case in sources["manifest"][::10]:
        folder = str(Path(case.names).parent) if case.names.endswith(".csv") else case.names
        out.append(
            Case(
                "cli",
                f"ingest {case.label}",
                lambda f=folder: call(["ingest", f, "-o", str(tmp / "i.nc"), "--no-progress"]),
                "",
            )
        )
    real = sources["datasets"][0].names
    out.append(
        Case(
            "cli",
            "diagnose bad --sim",
            lambda: call(
                ["diagnose", real, "--sim", sources["experiment"][0].names, "-o", str(tmp / "d")]
            ),
            "",
        )
    )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="seed of the random mutations")
    parser.add_argument("--examples", type=int, default=3, help="examples printed per problem")
    args = parser.parse_args()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # decoder chatter on stderr
    rng = random.Random(args.seed)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="simgap-fuzz-") as tmp_name:
        tmp = Path(tmp_name)
        _capture(tmp / "seed")
        families = {
            "experiment": experiment_cases(tmp, rng),
            "calibration": calibration_cases(tmp, rng),
            "manifest": manifest_cases(tmp, rng),
            "images": image_cases(tmp, rng),
            "datasets": dataset_cases(tmp, rng),
            "lying": lying_cases(tmp, rng),
            "damaged": damaged_bag_cases(tmp, rng),
        }
        families["cli"] = cli_cases(tmp, families)
        scenario = make_scenario(tmp / "outputs")
        families["outputs"] = [
            Case("outputs", label, lambda c=c: ("cli", *run_case(scenario, c)), "")
            for label, c in OUTPUT_CASES.items()
        ]
        results: dict[str, Counter] = defaultdict(Counter)
        examples: dict[tuple[str, str], list[str]] = defaultdict(list)
        for family, cases in families.items():
            for case in cases:
                kind, detail = outcome(case)
                results[family][kind] += 1
                if kind != "named":
                    examples[family, kind].append(f"{case.label}: {detail}")
    print(f"{'family':12s} {'inputs':>6s} {'named %':>8s} {'raw':>5s} {'accepted':>8s}")
    total: Counter = Counter()
    for family, counts in results.items():
        n = sum(counts.values())
        total.update(counts)
        print(
            f"{family:12s} {n:6d} {100 * counts['named'] / n:8.1f} {counts['raw']:5d} "
            f"{counts['accepted']:8d}"
        )
    n = sum(total.values())
    files = n - sum(results["cli"].values()) - sum(results["outputs"].values())
    print(
        f"{'total':12s} {n:6d} {100 * total['named'] / n:8.1f} {total['raw']:5d} "
        f"{total['accepted']:8d}   ({files} generated bad inputs + {n - files} CLI calls, "
        f"{time.perf_counter() - t0:.0f} s)"
    )
    for (family, kind), lines in sorted(examples.items()):
        print(f"\n{kind} in {family} ({len(lines)}), e.g.:")
        for line in lines[: args.examples]:
            print(f"  {' '.join(line.split())[:300]}")
    print(f"\n25000 x 25000 px frame refused (target: under {BIG_FRAME_TARGET_MB} MB):")
    with tempfile.TemporaryDirectory(prefix="simgap-big-") as tmp_name:
        for peak in big_frame_peaks(Path(tmp_name)):
            print(
                f"  {peak.label:24s} exit {peak.exit_code}, peak {peak.peak_mib:5.0f} MiB "
                f"({peak.peak_mib * 2**20 / 1e6:.0f} MB), whole simgap ingest process: "
                f"{' '.join(peak.message.split())[:150]}"
            )


if __name__ == "__main__":
    main()
