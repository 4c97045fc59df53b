"""Camera pipeline basics: linear HDR <-> EXR, sRGB 8-bit encoding, crops pasted into frames.

The linear render is the scene stage's product; everything here is the image stage (DESIGN §2).
EXR files hold half floats; the pipeline always works from the half-float values (also right after
rendering) so that a run served from cache gives bit-identical frames.
"""

from __future__ import annotations

from pathlib import Path

import colour
import cv2
import numpy as np
import OpenEXR

from simgap.atomic import atomic_write


def quantise_half(hdr: np.ndarray) -> np.ndarray:
    """Round linear RGB to half precision (as stored in EXR) and return float32."""
    return np.asarray(hdr, dtype=np.float16).astype(np.float32)


def write_exr(path: Path, hdr: np.ndarray) -> None:
    """Write linear RGB (H, W, 3) as a half-float, ZIP-compressed EXR, atomically."""
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def write(tmp: Path) -> None:
        with OpenEXR.File(header, {"RGB": np.ascontiguousarray(hdr, dtype=np.float16)}) as f:
            f.write(str(tmp))

    atomic_write(Path(path), write)


def read_exr(path: Path) -> np.ndarray:
    """Read an RGB EXR written by :func:`write_exr` as float32 (H, W, 3)."""
    with OpenEXR.File(str(path)) as f:
        return np.asarray(f.channels()["RGB"].pixels, dtype=np.float32)


def encode_srgb8(linear: np.ndarray) -> np.ndarray:
    """Encode linear RGB in [0, 1] with the sRGB transfer function to uint8 (round to nearest)."""
    encoded = colour.cctf_encoding(np.clip(linear, 0.0, 1.0), function="sRGB")
    return np.clip(np.round(encoded * 255.0), 0, 255).astype(np.uint8)


def paste(crop: np.ndarray, offset: tuple[int, int], size: tuple[int, int]) -> np.ndarray:
    """Paste ``crop`` at ``offset`` (x0, y0 px) into a frame of ``size`` (W, H px).

    The rest of the frame is filled with the median of the crop's border pixels, so that the
    detector sees a full-size frame without spurious edges at the crop boundary.
    """
    w, h = size
    x0, y0 = offset
    border = np.concatenate([crop[0], crop[-1], crop[:, 0], crop[:, -1]])
    frame = np.empty((h, w) + crop.shape[2:], dtype=crop.dtype)
    frame[...] = np.median(border, axis=0).astype(crop.dtype)
    ch, cw = crop.shape[:2]
    frame[y0 : y0 + ch, x0 : x0 + cw] = crop
    return frame


def write_png(path: Path, rgb8: np.ndarray) -> None:
    """Write an 8-bit RGB frame as PNG, atomically."""
    path = Path(path)
    ok, buf = cv2.imencode(
        ".png", cv2.cvtColor(rgb8, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 1]
    )
    if not ok:
        raise OSError(f"could not write {path}")
    atomic_write(path, buf.tobytes())


def to_gray(rgb8: np.ndarray) -> np.ndarray:
    """Convert an 8-bit RGB frame to 8-bit grey (ITU-R BT.601 weights, as OpenCV does)."""
    return rgb8 if rgb8.ndim == 2 else cv2.cvtColor(rgb8, cv2.COLOR_RGB2GRAY)
