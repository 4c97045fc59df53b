"""Camera pipeline basics: linear HDR <-> EXR, sRGB 8-bit encoding, crops pasted into frames.

The linear render is the scene stage's product; everything here is the image stage
(docs/conventions.md §2). EXR files hold half floats; the pipeline always works from the half-float
values (also right after rendering) so that a run served from cache gives bit-identical frames.
"""

from __future__ import annotations

import io
from pathlib import Path

import colour
import cv2
import numpy as np
import OpenEXR

from simgap.core.atomic import atomic_write

#: Largest finite half-precision value: radiance beyond it (the sun's disc seen directly, its
#: glint on bare metal) saturates there instead of becoming infinite.
HALF_MAX = float(np.finfo(np.float16).max)


def quantise_half(hdr: np.ndarray) -> np.ndarray:
    """Round linear RGB to half precision (as stored in EXR; saturated at :data:`HALF_MAX`)."""
    return np.minimum(np.asarray(hdr, np.float32), HALF_MAX).astype(np.float16).astype(np.float32)


def write_exr(path: Path, hdr: np.ndarray, exclusive: bool = False) -> None:
    """Write linear RGB (H, W, 3) as a half-float, ZIP-compressed EXR, atomically.

    With ``exclusive``, only when ``path`` does not exist yet (FileExistsError otherwise; see
    :func:`simgap.core.atomic.atomic_write`).
    """
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def write(tmp: Path) -> None:
        rgb = np.ascontiguousarray(np.minimum(hdr, HALF_MAX), dtype=np.float16)
        with OpenEXR.File(header, {"RGB": rgb}) as f:
            f.write(str(tmp))

    atomic_write(Path(path), write, exclusive=exclusive)


def read_exr(path: Path, size: tuple[int, int] | None = None) -> np.ndarray:
    """Read an RGB EXR written by :func:`write_exr` as float32 (H, W, 3).

    Parameters
    ----------
    path : Path
        The file.
    size : tuple of int, optional
        Expected ``(width, height)`` (px); a file of another size is an error.

    Raises
    ------
    ValueError, RuntimeError
        If the file is truncated, corrupt, has no RGB channels or the wrong size.
    """
    with OpenEXR.File(str(path)) as f:
        hdr = np.asarray(f.channels()["RGB"].pixels, dtype=np.float32)
    if hdr.ndim != 3 or hdr.shape[2] != 3:
        raise ValueError(f"{path}: expected RGB pixels (H, W, 3), got shape {hdr.shape}")
    if size is not None and hdr.shape[:2] != (size[1], size[0]):
        raise ValueError(
            f"{path}: expected {size[0]}x{size[1]} px, got {hdr.shape[1]}x{hdr.shape[0]}"
        )
    return hdr


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


#: PNG settings of every frame simgap writes: fastest zlib level and no row filter (lossless
#: whatever the settings; on a 1920x1080 frame 40 ms instead of 93 ms with the adaptive filters
#: when the stickers' surround is flat, 264 instead of 379 ms for a camera frame, 7 % larger).
PNG_WRITE_PARAMS = (
    cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE,
)  # fmt: skip


def encode_png(bgr: np.ndarray) -> bytes:
    """An 8-bit BGR (or grey) image encoded as PNG with :data:`PNG_WRITE_PARAMS`."""
    ok, buf = cv2.imencode(".png", bgr, list(PNG_WRITE_PARAMS))
    if not ok:
        raise ValueError(f"a {bgr.dtype} {bgr.shape} image cannot be encoded as PNG")
    return buf.tobytes()


def write_png(path: Path, rgb8: np.ndarray) -> None:
    """Write an 8-bit RGB frame as PNG, atomically."""
    atomic_write(Path(path), encode_png(cv2.cvtColor(rgb8, cv2.COLOR_RGB2BGR)))


#: Signatures and end markers of the encoded frames simgap reads (PNG spec §5.2, §11.2.5;
#: JPEG ITU-T T.81 Table B.1).
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_IEND_CHUNK = b"\x00\x00\x00\x00IEND\xaeB`\x82"
JPEG_SOI, JPEG_EOI = b"\xff\xd8", b"\xff\xd9"


def truncation(data: bytes) -> str | None:
    """Why an encoded PNG or JPEG is incomplete, or None when it ends as its format requires.

    Decoders fill a truncated image with grey or return what they have with a warning on
    stderr, so truncation is checked on the bytes: a PNG must end with its ``IEND`` chunk and a
    JPEG with the end-of-image marker ``FF D9`` (trailing zero padding allowed). Other formats
    are left to the decoder.
    """
    end = data.rstrip(b"\x00")
    if data.startswith(PNG_SIGNATURE) and not end.endswith(PNG_IEND_CHUNK):
        return "truncated PNG (no IEND chunk at the end)"
    if data.startswith(JPEG_SOI) and not end.endswith(JPEG_EOI):
        return "truncated JPEG (no end-of-image marker FF D9 at the end)"
    return None


def png_bit_depth(data: bytes) -> int | None:
    """Bit depth per sample of a PNG (from its IHDR chunk), or None for other data."""
    if not data.startswith(PNG_SIGNATURE) or len(data) < 25 or data[12:16] != b"IHDR":
        return None
    return data[24]


def encoded_size(data: bytes) -> tuple[int, int] | None:
    """Width and height (px) of an encoded PNG or JPEG from its header alone, or None.

    The size comes from the PNG ``IHDR`` chunk or the JPEG start-of-frame segment, read by
    Pillow's format plugins, which parse the header and decode nothing (so there is no
    decompression-bomb check either: the caller compares the size with what it expects before
    any decoder sees the data). None for other data and for a header that cannot be parsed.
    """
    from PIL import JpegImagePlugin, PngImagePlugin

    if data.startswith(PNG_SIGNATURE):
        plugin = PngImagePlugin.PngImageFile
    elif data.startswith(JPEG_SOI):
        plugin = JpegImagePlugin.JpegImageFile
    else:
        return None
    try:
        with plugin(io.BytesIO(data)) as image:
            return image.size
    except (OSError, SyntaxError, ValueError, EOFError, IndexError):  # a damaged header
        return None


def read_png(path: Path) -> np.ndarray:
    """Read an 8-bit RGB PNG written by :func:`write_png` (complete files only).

    Raises
    ------
    ValueError
        If the file is not a PNG, is truncated or cannot be decoded.
    """
    data = Path(path).read_bytes()
    why = truncation(data) if data.startswith(PNG_SIGNATURE) else "not a PNG file"
    bgr = None if why else cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ValueError(f"{path}: {why or 'cannot be decoded'}")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


#: Weights of R, G and B in the grey frame (ITU-R BT.601 luma, as ``cv2.COLOR_RGB2GRAY``).
GRAY_WEIGHTS = (0.299, 0.587, 0.114)
#: Variance of the grey frame per unit variance of independent, equal noise in R, G and B: the
#: sum of the squared :data:`GRAY_WEIGHTS` (dimensionless).
GRAY_NOISE_VARIANCE_RATIO = sum(w * w for w in GRAY_WEIGHTS)


def to_gray(rgb8: np.ndarray) -> np.ndarray:
    """Convert an 8-bit RGB frame to 8-bit grey (:data:`GRAY_WEIGHTS`, as OpenCV does)."""
    return rgb8 if rgb8.ndim == 2 else cv2.cvtColor(rgb8, cv2.COLOR_RGB2GRAY)
