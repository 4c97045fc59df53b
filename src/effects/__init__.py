"""The effects catalogue: every physical or algorithmic effect as a small registered class.

Each effect has a frozen, validated ``Params`` dataclass (units in the field names or docstring), a
docstring saying what it models, and the ``stage`` at which it acts (docs/conventions.md §2). The
class header registers it, ``class TagGloss(Effect, name="tag_gloss", stage="scene")``, and each
parameter declares its valid range once with :func:`~simgap.effects.base.param`. The stages:

==============  ==========================================================  =====================
stage           what it changes                                              recompute
==============  ==========================================================  =====================
``scene``       the rendered world: lights, materials, optics, true camera  re-render
``geometry``    the true fixture (the CAD ground truth is unchanged)         re-render
``image``       the camera pipeline on the cached linear render              re-process the EXR
``estimation``  what the estimator assumes: calibration, detector, PnP       re-detect / re-solve
==============  ==========================================================  =====================

An effect is applied to a :class:`~simgap.effects.state.VariantState` and returns a new one; the
sweep derives each stage's cache key from that stage's part of the state only, so a variant reuses
everything upstream of the first stage it changes.

Use :func:`make_effect` to build one from YAML data and ``EFFECTS`` to list them.
"""

from __future__ import annotations

from simgap.effects import (  # noqa: F401,E402  (registration)
    camera_pipeline,
    estimation,
    geometry,
    image,
    scene,
)
from simgap.effects.base import EFFECTS, Check, Effect, EffectParams, make_effect, param, register

__all__ = ["EFFECTS", "Check", "Effect", "EffectParams", "make_effect", "param", "register"]
