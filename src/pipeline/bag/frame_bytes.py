"""A bag's image message as the bytes of an image file, after checking it describes its data.

A ``CompressedImage`` keeps its own PNG or JPEG bytes (ingest reads their size from the header
before decoding); a raw ``Image`` is checked against its encoding (bytes a pixel, step, data
length; 16-bit refused, as in capture folders) and written as a PNG.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import numpy as np

from simgap.core.config import ConfigError, shown
from simgap.core.rig import CameraModel
from simgap.pipeline.bag.formats import COMPRESSED_TYPE
from simgap.render import imaging

#: Bytes a pixel takes in each 8-bit encoding of ``sensor_msgs/image_encodings`` that simgap
#: converts (grey and Bayer 1, YUV 4:2:2 2, colour 3 or 4), and the rows a frame holds per image
#: row (NV12 / NV21: a luma plane and a half-height chroma plane, 1.5).
RAW_ENCODINGS: dict[str, tuple[int, float]] = {
    **dict.fromkeys(
        ("mono8", "8UC1", "bayer_rggb8", "bayer_bggr8", "bayer_gbrg8", "bayer_grbg8"), (1, 1.0)
    ),
    **dict.fromkeys(("uyvy", "yuv422", "yuyv", "yuv422_yuy2", "8UC2"), (2, 1.0)),
    **dict.fromkeys(("bgr8", "rgb8", "8UC3"), (3, 1.0)),
    **dict.fromkeys(("bgra8", "rgba8", "8UC4"), (4, 1.0)),
    **dict.fromkeys(("nv12", "nv21"), (1, 1.5)),
}
#: 16-bit encodings: refused as capture folders refuse 16-bit PNGs (the scaling of 16-bit data
#: depends on the sensor's bit depth, which simgap does not guess; docs/conventions.md §3).
SIXTEEN_BIT = re.compile(r"^(mono16|bayer_\w+16|bgr16|rgb16|bgra16|rgba16|16[US]C\d)$")


def _raw_layout(msg: Any, where: str) -> Any:
    """``msg`` with rows unpadded, after its encoding, step and data length were checked.

    Raises ConfigError for a 16-bit or unknown encoding, a step shorter than the encoding's
    row, or data whose length is not step x rows (an encoding that lies about its data).
    """
    encoding = str(msg.encoding)
    if SIXTEEN_BIT.match(encoding):
        raise ConfigError(
            f"{where}: encoding: {encoding!r} is 16-bit; simgap reads 8-bit frames (their "
            "scaling depends on the sensor's bit depth, which it does not guess, as for 16-bit "
            "PNGs in a capture folder); convert the frames to 8 bits first"
        )
    if encoding not in RAW_ENCODINGS:
        raise ConfigError(
            f"{where}: encoding: expected an 8-bit encoding ({', '.join(RAW_ENCODINGS)}), "
            f"got {shown(encoding)}"
        )
    pixel_bytes, rows_per_row = RAW_ENCODINGS[encoding]
    width, height, step = int(msg.width), int(msg.height), int(msg.step)
    row, rows = width * pixel_bytes, int(round(height * rows_per_row))
    if step < row:
        raise ConfigError(
            f"{where}: step: {step} bytes a row, expected at least {row} ({width} px x "
            f"{pixel_bytes} bytes of {encoding})"
        )
    data = np.asarray(msg.data, np.uint8)
    if data.size != step * rows:
        raise ConfigError(
            f"{where}: data: {data.size} bytes, expected step x rows = {step} x {rows} = "
            f"{step * rows} for {encoding} at {width}x{height} (an encoding that does not "
            "describe the data?)"
        )
    if step == row:
        return msg
    unpadded = data.reshape(rows, step)[:, :row].reshape(-1)
    return dataclasses.replace(msg, data=np.ascontiguousarray(unpadded), step=row)


def frame_bytes(msg: Any, msgtype: str, where: str, cal: CameraModel) -> tuple[bytes, str]:
    """The frame as file bytes and extension: a CompressedImage's own bytes, else a PNG.

    A raw ``Image`` is converted only when its ``width`` and ``height`` fields match the
    calibration's and its encoding describes its data (:func:`_raw_layout`); a CompressedImage is
    kept as it is (ingest compares its header's size with the calibration before decoding it),
    except a 16-bit PNG, refused here with the topic and message.
    """
    if msgtype == COMPRESSED_TYPE:
        data = bytes(msg.data)
        if data.startswith(b"\x89PNG"):
            if imaging.png_bit_depth(data) == 16:
                raise ConfigError(
                    f"{where}: data: a 16-bit PNG; simgap reads 8-bit frames (their scaling "
                    "depends on the sensor's bit depth); convert the frames to 8 bits first"
                )
            return data, "png"
        if data.startswith(b"\xff\xd8"):
            return data, "jpg"
        return data, "img"  # undecodable: ingest records it as a detection failure
    from rosbags.image import ImageError, message_to_cvimage

    if (int(msg.width), int(msg.height)) != (cal.width, cal.height):
        raise ConfigError(
            f"{where}: width x height: expected {cal.width}x{cal.height} as the CameraInfo "
            f"states, got {int(msg.width)}x{int(msg.height)}"
        )
    msg = _raw_layout(msg, where)
    try:
        bgr = message_to_cvimage(msg, "bgr8")
    except (ImageError, ValueError, KeyError) as exc:
        raise ConfigError(
            f"{where}: encoding: expected an 8-bit encoding (mono8, bgr8, rgb8, ...), "
            f"got {msg.encoding!r}: {exc}"
        ) from None
    try:
        return imaging.encode_png(bgr), "png"
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None


__all__ = ["RAW_ENCODINGS", "SIXTEEN_BIT", "frame_bytes"]
