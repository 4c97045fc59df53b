"""The candidates: every effect the diagnosis can fit to a gap, its fit, and one registry by name.

One registry keyed by effect name (``CANDIDATES``, ``_registry``) holds every candidate; a
``Candidate`` is a ``ProjectionCandidate`` (effects that only move where corners project, fitted
on the detected corners, ``_fitting``; several jointly, ``_projection_set``; the size signature
of a print scale, ``_size_signature``; the camera's pipeline moving the marker edges,
``_edge_offset``) or a ``SimulationCandidate`` run through the pipeline by
the ``Runner`` it is given (``_runner``): the appearance effects fitted on image evidence
(``_appearance``, ``_exposure``, ``_black_level``, ``_sensor_noise``, ``_defocus``), the glossy
laminate (``_gloss`` on the levels of ``_tag_levels``, ``_glint_ratio``, ``_lobe``, with
``_subset_fit``), a light the simulation lacks (``_sun``), and a model's simulation effects
fitted one after another (``_simulation_chain``).

The modules are private; other packages import the names of ``__all__`` from here.
"""

from __future__ import annotations

from simgap.analysis.candidates._appearance import (
    AppearanceCandidate,
    agreed_dc_step,
    evidence_misfit,
    signature_significant,
)
from simgap.analysis.candidates._black_level import BlackLevelCandidate
from simgap.analysis.candidates._defocus import DISK_10_90_PER_RADIUS, DefocusCandidate
from simgap.analysis.candidates._edge_offset import EdgeOffsetCandidate
from simgap.analysis.candidates._exposure import (
    ExposureCandidate,
    censored_median_ev,
    ink_exposures,
)
from simgap.analysis.candidates._fitting import (
    Candidate,
    Fit,
    ProjectionCandidate,
    SimulationCandidate,
    on_bound,
    project_items,
)
from simgap.analysis.candidates._glint_ratio import (
    HEIGHT_M,
    HELD_OFFSETS_M,
    MIN_TAGS,
    fit_ratios,
    held_inside,
)
from simgap.analysis.candidates._gloss import (
    GLINT_MIN_GAIN,
    OFFSET_M,
    ROUGHNESS_RANGE,
    GlossCandidate,
    fit_levels,
    laminate_effects,
    laminate_explains,
    predicted_levels,
)
from simgap.analysis.candidates._lobe import beckmann, fresnel_veil, lobe_geometry
from simgap.analysis.candidates._projection_set import ProjectionSet
from simgap.analysis.candidates._registry import CANDIDATES, geometric_effects
from simgap.analysis.candidates._runner import Runner
from simgap.analysis.candidates._sensor_noise import FULL_WELL_BOUNDS_E, SensorNoiseCandidate
from simgap.analysis.candidates._simulation_chain import (
    SOFTNESS_EFFECTS,
    SimulationChain,
    refitted,
)
from simgap.analysis.candidates._size_signature import size_change
from simgap.analysis.candidates._sun import (
    RENDER_ELEVATION_DEG,
    PaperLevels,
    SunCandidate,
    SunFit,
    fit_sun,
    sun_effects,
)
from simgap.analysis.candidates._tag_levels import CLIPPED_DN, TagLevels

__all__ = [
    "AppearanceCandidate",
    "BlackLevelCandidate",
    "CANDIDATES",
    "CLIPPED_DN",
    "Candidate",
    "DISK_10_90_PER_RADIUS",
    "DefocusCandidate",
    "EdgeOffsetCandidate",
    "ExposureCandidate",
    "FULL_WELL_BOUNDS_E",
    "Fit",
    "GLINT_MIN_GAIN",
    "GlossCandidate",
    "HEIGHT_M",
    "HELD_OFFSETS_M",
    "MIN_TAGS",
    "OFFSET_M",
    "ProjectionCandidate",
    "ProjectionSet",
    "ROUGHNESS_RANGE",
    "RENDER_ELEVATION_DEG",
    "PaperLevels",
    "Runner",
    "SensorNoiseCandidate",
    "SimulationCandidate",
    "SOFTNESS_EFFECTS",
    "SimulationChain",
    "SunCandidate",
    "SunFit",
    "TagLevels",
    "agreed_dc_step",
    "beckmann",
    "censored_median_ev",
    "evidence_misfit",
    "fit_levels",
    "fit_ratios",
    "held_inside",
    "fit_sun",
    "fresnel_veil",
    "geometric_effects",
    "ink_exposures",
    "laminate_effects",
    "laminate_explains",
    "lobe_geometry",
    "on_bound",
    "predicted_levels",
    "project_items",
    "refitted",
    "signature_significant",
    "size_change",
    "sun_effects",
]
