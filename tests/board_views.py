"""Synthetic photos of a board of markers, for the tests of board photos."""

from __future__ import annotations

import cv2
import numpy as np

from simgap.core import transforms as tf
from simgap.core.board import Board
from simgap.core.rig import CameraModel


def synthetic_view(board: Board, camera: CameraModel, r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """An antialiased image of ``board`` at pose (r, t) through a pinhole ``camera``.

    ``r`` (rad) and ``t`` (m): the board's rotation vector and origin in the OpenCV camera frame.
    The board's print (8000 px/m) is warped at 4x the camera's resolution and averaged down
    (INTER_AREA), so every camera pixel integrates its footprint as a sensor does.
    """
    ppm, k = 8000, 4
    cols = board.columns * (board.square_m or 0.0)
    rows = board.rows * (board.square_m or 0.0)
    src = board.opencv.generateImage((int(cols * ppm), int(rows * ppm)), marginSize=0)
    to_m = np.array([[1 / ppm, 0, 0.5 / ppm], [0, 1 / ppm, 0.5 / ppm], [0, 0, 1]])
    up = np.array([[k, 0, (k - 1) / 2], [0, k, (k - 1) / 2], [0, 0, 1]])
    rot = tf.rotvec_to_matrix(r)
    h = up @ camera.matrix @ np.column_stack([rot[:, 0], rot[:, 1], t]) @ to_m
    big = cv2.warpPerspective(src, h, (camera.width * k, camera.height * k), borderValue=255)
    return cv2.resize(big, (camera.width, camera.height), interpolation=cv2.INTER_AREA)
