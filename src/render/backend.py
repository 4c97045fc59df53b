"""Choose and import the Mitsuba variant.

Dr.Jit's LLVM back end reads ``DRJIT_LIBLLVM_PATH`` when ``drjit`` is imported, and LLVM 15/16 abort
the whole process on the first kernel (docs/conventions.md §4). This module therefore finds the
newest libLLVM >= 19 *before* importing mitsuba, uses ``llvm_ad_rgb`` when one is found and falls
back to ``scalar_rgb`` (about 4x slower) with a warning otherwise. ``SIMGAP_VARIANT`` overrides the
choice.

Importing this module imports nothing of Mitsuba: :func:`mitsuba` is the renderer's one explicit
set-up (variant, then simgap's plugins), called when a scene is built.
"""

from __future__ import annotations

import glob
import os
import re
import warnings
from types import ModuleType

from simgap.render.camera import register_sensor

MIN_LLVM = 19
_LLVM_GLOBS = (
    "/usr/lib/*-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
)


def find_libllvm(min_major: int = MIN_LLVM) -> str | None:
    """Return the path of the newest libLLVM with major version >= ``min_major``, or None."""
    best: tuple[int, str] | None = None
    for pattern in _LLVM_GLOBS:
        for path in glob.glob(pattern):
            m = re.search(r"libLLVM[-.]?(?:so\.)?(\d+)", os.path.basename(path))
            if not m:
                continue
            major = int(m.group(1))
            if major >= min_major and (best is None or major > best[0]):
                best = (major, path)
    return best[1] if best else None


def choose_variant() -> str:
    """Return the Mitsuba variant to use, setting ``DRJIT_LIBLLVM_PATH`` when needed."""
    forced = os.environ.get("SIMGAP_VARIANT")
    if forced:
        if forced.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
            lib = find_libllvm()
            if lib:
                os.environ["DRJIT_LIBLLVM_PATH"] = lib
        return forced
    if "DRJIT_LIBLLVM_PATH" in os.environ:
        return "llvm_ad_rgb"
    lib = find_libllvm()
    if lib is None:
        warnings.warn(
            f"no libLLVM >= {MIN_LLVM} found (install Debian's libllvm19); rendering with the "
            "slower 'scalar_rgb' variant. Set SIMGAP_VARIANT to override.",
            RuntimeWarning,
            stacklevel=2,
        )
        return "scalar_rgb"
    os.environ["DRJIT_LIBLLVM_PATH"] = lib
    return "llvm_ad_rgb"


_MI: ModuleType | None = None


def mitsuba() -> ModuleType:
    """Set up the renderer once per process and return the ``mitsuba`` module.

    Imports mitsuba with the variant of :func:`choose_variant` and registers simgap's plugins (the
    OpenCV sensor, :func:`simgap.render.camera.register_sensor`).
    """
    global _MI
    if _MI is None:
        variant = choose_variant()
        import mitsuba as mi

        mi.set_variant(variant)
        register_sensor(mi)
        _MI = mi
    return _MI
