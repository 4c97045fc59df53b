"""The rig's own geometry found in simulated board photos measured against a robot's chain.

Six photos of OpenCV's tutorial ChArUco board (assets/real/opencv_charuco/board.yaml) through a
640 x 480 pinhole, its centre at 0.35-0.60 m and tilted 0.3 rad about six axes (:func:`views`),
rendered by simgap
(:class:`simgap.render.board_scene.BoardScene`, ``--spp`` samples, render seeds 100-105, sRGB)
at their true poses, stand in for a robot's photos. The robot's flange poses are made so that
its chain (flange poses, hand-eye, board in the base) gives the true poses; an error is then
written into the chain's files, and ``simgap ingest --board --robot-poses --hand-eye
--board-in-base --simulate`` (the same code: :func:`simgap.analysis.gap.diagnose_photos`)
renders the photos again at the chain's poses (render seeds 0-5), fits the camera and then the
rig (:func:`simgap.analysis.gap.fit_rig`) on the gap. Printed per case: the error written, the
model found with its values (mm, mrad, %) and jackknife sd, the look-alikes, and the gap's
depth and x per distance third after the camera, then after the camera and the rig
(cross-fitted).

Results: docs/results/real_photos.md ("The rig's own geometry").

Usage: ``python benchmarks/rig_fit.py [--spp 16]``
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import cv2
import numpy as np

from simgap.analysis.gap import diagnose_photos, parameter_text
from simgap.core import transforms as tf
from simgap.core.board import read_board
from simgap.core.rig import CameraModel
from simgap.pipeline.photo_references import (
    RobotReference,
    write_pose_csv,
    write_transform_file,
)
from simgap.pipeline.photos import measure_photos, photo_of
from simgap.render.board_scene import BoardScene
from simgap.scene.spec import default_scene_spec

BOARD = Path(__file__).resolve().parents[1] / "assets" / "real" / "opencv_charuco" / "board.yaml"
CAMERA = CameraModel(width=640, height=480, fx=600.0, fy=600.0, cx=319.5, cy=239.5)
#: Photos: the board's centre on the optical axis at these distances (m), tilted by
#: :data:`TILT_RAD` about an axis in the image plane turned by 360 / n deg from one photo to the
#: next, and turned about the optical axis by 0.2 rad a photo.
DISTANCES_M = (0.35, 0.40, 0.45, 0.50, 0.55, 0.60)
TILT_RAD = 0.3


def views(board_centre: np.ndarray) -> list[np.ndarray]:
    """The photos' true ``camera_from_board`` (4 x 4, m): :data:`DISTANCES_M`, :data:`TILT_RAD`."""
    out = []
    n = len(DISTANCES_M)
    for k, z in enumerate(DISTANCES_M):
        axis = np.array([np.cos(2 * np.pi * k / n), np.sin(2 * np.pi * k / n), 0.0])
        rot = tf.rotvec_to_matrix(TILT_RAD * axis) @ tf.rotvec_to_matrix([0.0, 0.0, 0.2 * k])
        out.append(tf.make(rot, np.array([0.0, 0.0, z]) - rot @ board_centre))
    return out


FLANGE_FROM_CAMERA = tf.make(tf.rotvec_to_matrix([0.1, 0.0, 0.0]), [0.03, -0.05, 0.12])
BASE_FROM_BOARD = tf.make(tf.rotvec_to_matrix([0.2, -0.1, 2.5]), [0.65, -0.2, 0.02])
#: Case -> (hand-eye error D: the given hand-eye is the true one times D; board error E: the
#: given board in the base is the true one times E^-1).
CASES = {
    "none": (np.eye(4), np.eye(4)),
    "hand-eye 2 mm along x, 5 mrad about y": (
        tf.make(tf.rotvec_to_matrix([0, 0.005, 0]), [0.002, 0, 0]),
        np.eye(4),
    ),
    "board 1 mm / -2 mm along its x / y, 4 mrad about its normal": (
        np.eye(4),
        tf.make(tf.rotvec_to_matrix([0, 0, 0.004]), [0.001, -0.002, 0]),
    ),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--spp", type=int, default=16)
    args = parser.parse_args()
    board = read_board(BOARD)
    scene = BoardScene(board, CAMERA, default_scene_spec(), args.spp)
    with tempfile.TemporaryDirectory(prefix="simgap-rig-") as tmp:
        folder = Path(tmp) / "photos"
        folder.mkdir()
        truth = {}
        centre = np.mean(board.chessboard_corners, axis=0)
        for f, pose in enumerate(views(centre)):
            name = f"photo_{f:02d}.png"
            photo = photo_of(scene.render(pose, 100 + f), CAMERA, seed=50 + f)
            cv2.imwrite(str(folder / name), photo)
            truth[name] = pose
        robot = write_pose_csv(
            Path(tmp) / "robot.csv",
            {
                n: BASE_FROM_BOARD @ tf.invert(c) @ tf.invert(FLANGE_FROM_CAMERA)
                for n, c in truth.items()
            },
        )
        for label, (hand_eye_error, board_error) in CASES.items():
            given = FLANGE_FROM_CAMERA @ hand_eye_error
            hand_eye = write_transform_file(Path(tmp) / "he.yaml", given)
            in_base = write_transform_file(
                Path(tmp) / "ib.yaml", BASE_FROM_BOARD @ tf.invert(board_error)
            )
            reference = RobotReference.read(robot, hand_eye, in_base)
            real = measure_photos(folder, board, CAMERA, reference=reference)
            diagnosis = diagnose_photos(real, board, CAMERA, spp=args.spp)
            rig = diagnosis.gaps.rig
            assert rig is not None
            print(f"{label}: {rig.sightings} sightings, {rig.frames} photos", flush=True)
            for m in rig.models:
                values = ", ".join(
                    f"{k} {parameter_text(k, v)} +- {parameter_text(k, m.std[k]).lstrip('+')}"
                    for k, v in m.parameters.items()
                )
                found = " FOUND" if m is rig.found else ""
                print(f"  {m.name}: {values}; weighted {m.misfit_before:.2f} -> "
                      f"{m.misfit_after:.2f}{found}")  # fmt: skip
            if rig.look_alikes:
                print(f"  look-alikes: {', '.join(rig.look_alikes)}")
            rows = [("after the camera", diagnosis.gaps.after["distance"])]
            if diagnosis.gaps.after_rig:
                rows.append(("after the camera and the rig", diagnosis.gaps.after_rig["distance"]))
            for what, bands in rows:
                cells = "; ".join(
                    f"{b.band} depth {b.gap_median_mm[2]:+.2f} x {b.gap_median_mm[0]:+.2f}"
                    for b in bands
                )
                print(f"  gap (mm), {what}: {cells}", flush=True)


if __name__ == "__main__":
    main()
