"""Limits on what simgap reads, light enough for the command line to import for its defaults."""

from __future__ import annotations

#: The pixel budget: frames are read (from capture folders and bags) only where the calibration's
#: image size is at most this many pixels, whatever it states, so a small file whose header and
#: calibration both claim 32000 x 32000 px is refused before any decode (its pixels would take
#: 3 GB as 8-bit colour). 50 MP covers real cameras (the largest machine-vision sensors, about
#: 50 MP; a RealSense D435i's colour sensor, 2.1 MP) and decodes to 150 MB as 8-bit colour.
#: ``simgap ingest --max-pixels`` raises it.
MAX_PIXELS = 50_000_000

#: Samples per pixel of a board photo's render (``ingest --board --simulate``): on OpenCV's
#: tutorial photos (markers of about 25 px) the median single-marker depth per distance third
#: moved by up to 2.1 mm between seeds at 64, by at most 0.3 mm from 256 to 1024
#: (docs/results/real_photos.md).
PHOTO_SPP = 256

__all__ = ["MAX_PIXELS", "PHOTO_SPP"]
