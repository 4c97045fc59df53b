"""A board of markers rendered at a photo's pose through its calibration (the rig beyond PASS).

The board (:class:`simgap.core.board.Board`) is one Mitsuba ``rectangle`` whose diffuse albedo
is the board's print on its sheet: OpenCV's own image of the board (``generateImage``) with a
paper margin around it, each texel ink or paper (the scene's tag print,
:class:`simgap.scene.materials.TagPrint`), looked up with the print's texture filter
(:func:`simgap.render.mitsuba_scene.tag_bsdf`). Behind the sheet lies a diffuse backdrop (a
desk). The camera is simgap's OpenCV sensor (:mod:`simgap.render.camera`: every distortion model,
per ray) at the photo's reference pose (docs/conventions.md §6); the light a uniform ambient of
unit radiance, so that a paper's linear level is its albedo. The scene frame is the board frame
(m).
"""

from __future__ import annotations

import copy
from typing import Any, Final

import numpy as np

from simgap.core import transforms as tf
from simgap.core.board import Board
from simgap.core.limits import PHOTO_SPP
from simgap.core.rig import CameraModel
from simgap.render.backend import mitsuba
from simgap.render.mitsuba_scene import bsdf, tag_bsdf
from simgap.render.scene import PixelTracer, sensor_dict
from simgap.scene.materials import Diffuse
from simgap.scene.spec import SceneSpec

#: Texels of the board's print per metre: 4 per mm puts a whole number of texels in every
#: square and marker cell of boards drawn in whole millimetres (a 2.5 mm cell: 10 texels).
TEXELS_PER_M: Final[int] = 4000
#: Grey level above which a texel of OpenCV's board image is paper (its image is 0 or 255).
PAPER_GREY: Final[int] = 127
#: Paper around the board on its sheet (m): an A4 sheet's margin around a 200 x 280 mm board.
SHEET_MARGIN_M: Final[float] = 0.005
#: Albedo of the backdrop behind the sheet (a grey desk; dimensionless).
BACKDROP_ALBEDO: Final[float] = 0.3
#: The backdrop's distance behind the sheet (m) and its half-size (m).
BACKDROP_BEHIND_M: Final[float] = 0.001
BACKDROP_HALF_M: Final[float] = 2.0


def board_size_m(board: Board) -> tuple[float, float]:
    """Width and height of the board's printed area (m), without the sheet's margin."""
    if board.kind == "charuco":
        side = float(board.square_m)  # type: ignore[arg-type]
        return board.columns * side, board.rows * side
    sep = float(board.separation_m)  # type: ignore[arg-type]
    return (
        board.columns * (board.marker_m + sep) - sep,
        board.rows * (board.marker_m + sep) - sep,
    )


def board_albedo(board: Board, ink: float, paper: float, margin_m: float) -> np.ndarray:
    """The sheet's print as linear albedo (rows x columns, float32), margin included."""
    width_m, height_m = board_size_m(board)
    margin = round(margin_m * TEXELS_PER_M)
    size = (round(width_m * TEXELS_PER_M) + 2 * margin, round(height_m * TEXELS_PER_M) + 2 * margin)
    grey = board.opencv.generateImage(size, marginSize=margin, borderBits=1)
    return np.where(grey > PAPER_GREY, paper, ink).astype(np.float32)


def _rectangle(x0: float, y0: float, x1: float, y1: float, z: float) -> np.ndarray:
    """A ``rectangle``'s to_world (4x4) onto [x0, x1] x [y0, y1] at depth z of the board frame.

    Local y = +1 (texel row 0) goes to y0 (the board's top); the normal faces -z (the camera).
    """
    out = np.diag([(x1 - x0) / 2, -(y1 - y0) / 2, -1.0, 1.0])
    out[:3, 3] = (x0 + x1) / 2, (y0 + y1) / 2, z
    return out


class BoardScene(PixelTracer):
    """A board posed in front of a calibrated camera, rendered by path tracing.

    Parameters
    ----------
    board : Board
        The printed board.
    camera : CameraModel
        The camera that takes the picture (its image size is the film's).
    spec : SceneSpec
        Integrator, pixel filter and tag print (ink, paper, texture filter) of the scene.
    spp : int
        Samples per pixel.
    margin_m : float
        Paper around the board on its sheet (m).
    """

    def __init__(
        self,
        board: Board,
        camera: CameraModel,
        spec: SceneSpec,
        spp: int = PHOTO_SPP,
        margin_m: float = SHEET_MARGIN_M,
    ) -> None:
        self.mi = mi = mitsuba()
        self.board, self.camera_model, self.spec = board, camera, spec
        width_m, height_m = board_size_m(board)
        albedo = board_albedo(board, spec.tag.ink, spec.tag.paper, margin_m)
        m, h = margin_m, BACKDROP_HALF_M
        scene: dict[str, Any] = {
            "type": "scene",
            "integrator": copy.deepcopy(spec.integrator),
            "sensor": sensor_dict((camera.width, camera.height), spec.rfilter, "multijitter", spp),
            "sheet": {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f(_rectangle(-m, -m, width_m + m, height_m + m, 0)),
                "bsdf": tag_bsdf(spec.tag, albedo, mi),
            },
            "backdrop": {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f(_rectangle(-h, -h, h, h, BACKDROP_BEHIND_M)),
                "bsdf": bsdf(Diffuse(reflectance=BACKDROP_ALBEDO)),
            },
            "ambient": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
        }
        self.scene = mi.load_dict(scene)
        self.camera = self.scene.sensors()[0]
        self.spp = int(self.camera.sampler().sample_count())
        c = camera
        self.camera.set_intrinsics(c.fx, c.fy, c.cx, c.cy, c.distortion, c.distortion_model)
        self.camera.set_lens(0.0, 1.0)
        self.pose: np.ndarray | None = None

    def render(self, camera_from_board: np.ndarray, seed: int = 0) -> np.ndarray:
        """The linear RGB image (height, width, 3) with the board at ``camera_from_board`` (4x4).

        ``camera_from_board`` takes board-frame points (m) to the OpenCV camera frame (a
        photo's reference pose, :meth:`simgap.pose.board_pose.BoardView.camera_from_board`).
        """
        self.camera.set_pose(tf.invert(camera_from_board))
        self.pose = np.asarray(camera_from_board, float)
        w, h = self.camera_model.width, self.camera_model.height
        rows, cols = np.mgrid[0:h, 0:w]
        pixels = np.stack([cols.ravel(), rows.ravel()], axis=1)
        return self.render_pixels(pixels, seed).reshape(h, w, 3)


__all__ = [
    "BACKDROP_ALBEDO",
    "PAPER_GREY",
    "SHEET_MARGIN_M",
    "TEXELS_PER_M",
    "BoardScene",
    "board_albedo",
    "board_size_m",
]
