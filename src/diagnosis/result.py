"""The diagnosis's result as typed records: where, ranking, selection, combined, confirmed.

:class:`DiagnosisResult` is what :func:`simgap.diagnosis.diagnose.diagnose` returns and what
``result.json`` holds (:meth:`DiagnosisResult.to_json`, :meth:`DiagnosisResult.from_json`;
docs/diagnosis.md documents the schema). Three splits of the comparable items (a tag at a
configuration, docs/conventions.md §7), one name each:
*fit* (the effects' parameters are fitted), *choose* (models are ranked, combined, simplified and
pruned: :class:`RankedEffect`, :class:`Selection`) and *measure* (the chosen model is measured:
:class:`Combined`, :class:`Confirmed`).

Schema versions: 3 (this one); 2 (the measure split was ``report``, counts of items were
``configurations``) and 1 (no ``schema_version``
key: the splits were ``train`` / ``heldout`` / ``report`` and most scores had a ``heldout_`` prefix
whatever their split) are still read (:func:`upgrade_v2`, :func:`upgrade_v1` then
:func:`upgrade_v2`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

from simgap.analysis.gap import (
    AxisGap,
    DetectionRates,
    DetectionTest,
    ImageTest,
    RegionGap,
    ScatterTest,
    root_sum_square,
)
from simgap.analysis.search import Scored
from simgap.core.axes import AXES
from simgap.diagnosis.result_json import VersionedRecord

#: Version of the ``result.json`` schema written.
SCHEMA_VERSION = 3
NAN = float("nan")


@dataclass(kw_only=True)
class Where:
    """Where the gap lies: the pose gap per axis and region, and the evidence tests."""

    significant: bool = False
    #: evidence families with a significant difference: pose, scatter, detection, image
    significant_evidence: list[str] = field(default_factory=list)
    axis_gaps: dict[str, AxisGap] = field(default_factory=dict)
    #: significant regions of the pose gap only
    regions: list[RegionGap] = field(default_factory=list)
    detection: DetectionRates | None = None
    scatter_tests: list[ScatterTest] = field(default_factory=list)
    detection_tests: list[DetectionTest] = field(default_factory=list)
    image_tests: list[ImageTest] = field(default_factory=list)
    comparable_items: int = 0


@dataclass(kw_only=True)
class Scores:
    """A model's misfit of the evidence of one split, before and after its effects.

    ``*_before``: the simulation alone; ``*_after``: with the model's effects. Units as
    :class:`simgap.analysis.search.Scored`'s: ``pose_gap`` on the axes with a significant gap,
    ``pose_gap_all_axes``, ``median_abs_gap`` per axis (m or rad), ``corner_gap_*_px``,
    ``image_misfit`` (root sum of squares over the image statistics, floors),
    ``detection_mismatch`` (5 % units) and ``evidence`` (all channels combined); the reductions
    are relative falls. Scores that a schema-1 file did not keep are NaN (per axis: empty).
    """

    pose_gap_before: float = NAN
    pose_gap_after: float = NAN
    pose_gap_reduction: float = NAN
    pose_gap_all_axes_before: float = NAN
    pose_gap_all_axes_after: float = NAN
    median_abs_gap_before: dict[str, float] = field(default_factory=dict)
    median_abs_gap_after: dict[str, float] = field(default_factory=dict)
    corner_gap_before_px: float = NAN
    corner_gap_after_px: float = NAN
    image_misfit_before: float = NAN
    image_misfit_after: float = NAN
    detection_mismatch_before: float = NAN
    detection_mismatch_after: float = NAN
    evidence_before: float = NAN
    evidence_after: float = NAN
    evidence_reduction: float = NAN

    @classmethod
    def of(cls, scored: Scored) -> Scores:
        """The scores of a scored model: its values of the same names (arrays reduced)."""
        values = {f.name: getattr(scored, f.name) for f in fields(cls)}
        for side in ("before", "after"):
            values[f"median_abs_gap_{side}"] = per_axis(values[f"median_abs_gap_{side}"])
            values[f"image_misfit_{side}"] = root_sum_square(values[f"image_misfit_{side}"])
        return cls(**values)


@dataclass(kw_only=True)
class RankedEffect:
    """One candidate alone, fitted on the fit split and scored on the choose split."""

    effect: str
    params: dict[str, Any]
    n_params: int
    #: "projection" (fitted on the corners) or "appearance" (on the image evidence)
    kind: str
    fit_seconds: float
    scores: Scores

    @classmethod
    def of(cls, scored: Scored) -> RankedEffect:
        """The ranking entry of a single-effect model."""
        cand, fit = scored.fits[0]
        return cls(
            effect=fit.effect,
            params=fit.params,
            n_params=cand.n_params,
            kind=cand.kind,
            fit_seconds=fit.seconds,
            scores=Scores.of(scored),
        )


@dataclass(kw_only=True)
class Finding:
    """One selected effect with its fitted parameters.

    Attributes
    ----------
    effect : str
        Catalogue name.
    params : dict
        Fitted parameters, in the units the effect's params declare.
    pose_contribution : float
        How far it moves the choose split's poses, the other effects held at their fitted values
        (:meth:`simgap.analysis.search.ModelSearch.contributions`).
    minor : bool
        Seen in the corners or images, moves no pose beyond the floor.
    at_bound : list of str
        Its parameters fitted on the end of their searched range
        (:func:`simgap.analysis.search.at_bound`; empty for every finding the search admits,
        recorded so that validation measures it).
    look_alikes : list of str
        For a minor geometric or calibration finding, the effects that explain the evidence as
        well in its place (:func:`simgap.analysis.search.corner_look_alikes`): the corners do not
        single it out, so the finding is undecided between it and them (empty: decided).
    """

    effect: str
    params: dict[str, Any]
    pose_contribution: float
    minor: bool
    at_bound: list[str] = field(default_factory=list)
    look_alikes: list[str] = field(default_factory=list)

    @property
    def undecided(self) -> bool:
        """The capture's poses cannot tell this finding from its look-alikes."""
        return bool(self.look_alikes)


@dataclass(kw_only=True)
class TellingPose:
    """A grid pose where two look-alike models predict different corners.

    (:func:`simgap.diagnosis.telling_poses.telling_poses`.)
    """

    p: int
    theta_deg: float
    #: the tag at that pose whose corners differ most
    tag: int
    #: camera-to-tag distance (m)
    distance_m: float
    #: RMS distance between the two models' predicted corners (px)
    corner_difference_px: float


@dataclass(kw_only=True)
class EquivalentModel:
    """A model tried that the choose split cannot tell from the chosen one."""

    effects: list[str]
    n_params: int
    scores: Scores
    #: the largest RMS corner distance (px) between it and the chosen model over the capture's
    #: own poses (None: not computed, e.g. a refused model)
    capture_difference_px: float | None = None
    #: the grid poses where the two differ most (empty where neither has geometry)
    telling_poses: list[TellingPose] = field(default_factory=list)


@dataclass(kw_only=True)
class Selection:
    """The chosen model: its findings (most important first) and its scores on the choose split."""

    findings: list[Finding]
    n_params: int
    #: items of the choose split
    items: int
    scores: Scores
    equivalent_models: list[EquivalentModel] = field(default_factory=list)


@dataclass(kw_only=True)
class Combined:
    """The chosen model measured on the measure split (neither fitted nor chose it).

    The intervals are 90 % bootstrap intervals ([low, high]) of the scores' reductions.
    """

    #: items of the measure split
    items: int
    scores: Scores
    pose_gap_reduction_interval_90: tuple[float, float]
    evidence_reduction_interval_90: tuple[float, float]


@dataclass(kw_only=True)
class Confirmed:
    """The measure split re-run through the full pipeline (re-rendered) with the fitted effects."""

    #: items of the measure split
    items: int
    pose_gap_after: float
    pose_gap_reduction: float
    median_abs_gap_after: dict[str, float]
    seconds: float


@dataclass(kw_only=True)
class Split:
    """Sizes of the fit, choose and measure splits, and the seed that drew them."""

    fit: int
    choose: int
    measure: int
    seed: int


@dataclass(kw_only=True)
class Demosaicing:
    """The Bayer colour filter array a capture's colour frames show, as the simulation images it.

    Read from the frames at ingest (:class:`simgap.pose.cfa.CfaVerdict`) and applied to the
    simulation (``bayer`` effect), as a property of the camera, not a cause of the gap.
    """

    #: the 2 x 2 filter tile at the frame's top-left pixel, e.g. ``"RGGB"``
    layout: str
    #: the catalogue's demosaicing method nearest the camera's (``bilinear``, ``edge_aware``)
    method: str
    #: the layout's re-mosaicking residual over the other layouts' (1: no trace; 0: exact)
    residual_ratio: float
    #: the power-law tone response (code value ** gamma = linear) in whose linear light the
    #: frames are reproduced best (:data:`simgap.pose.cfa.TRANSFER_GAMMAS`); None in results
    #: from before it was read
    transfer_gamma: float | None = None


@dataclass(kw_only=True)
class PipelineSignature:
    """What a capture and its simulation show of one stage of a camera's own image pipeline.

    (:func:`simgap.diagnosis.camera_signatures.pipeline_signatures`.)
    """

    #: the stage, e.g. ``"sharpening"``
    stage: str
    #: what is measured, with its unit
    measure: str
    #: the capture's value (None: not measurable, e.g. no colour or one frame a pose)
    real: float | None
    #: the simulation's value
    simulated: float | None


@dataclass(kw_only=True)
class EdgeOffset:
    """How the capture's marker sizes differ from the simulation's: a share and an offset.

    The per-tag size change real - simulated regressed on the simulated size over every
    comparable item (:func:`simgap.diagnosis.camera_signatures.edge_offset`). A scale (a print
    scale, a focal length) changes a marker's size by a share of it; a camera pipeline the
    simulation lacks (a black level, a tone curve, demosaicing on soft edges) moves its edges by
    about the same pixels at every size: the offset.
    """

    #: tags regressed
    tags: int
    #: the size change at zero size (px; positive: the capture's markers larger)
    offset_px: float
    #: the size change per px of size (a share; 0.01: 1 % larger)
    scale_share: float
    #: ``scale_share`` over its standard error
    scale_z: float


#: Schema 1 keys renamed in schema 2, per record.
_V1_RANKED = {
    "heldout_gap_before": "pose_gap_before",
    "heldout_gap_after": "pose_gap_after",
    "reduction": "pose_gap_reduction",
    "heldout_gap_all_axes_before": "pose_gap_all_axes_before",
    "heldout_gap_all_axes_after": "pose_gap_all_axes_after",
    "heldout_corner_gap_before_px": "corner_gap_before_px",
    "heldout_corner_gap_after_px": "corner_gap_after_px",
    "heldout_gap_before_per_axis": "median_abs_gap_before",
    "heldout_gap_after_per_axis": "median_abs_gap_after",
    "heldout_image_misfit_before": "image_misfit_before",
    "heldout_image_misfit_after": "image_misfit_after",
    "heldout_detection_mismatch_before": "detection_mismatch_before",
    "heldout_detection_mismatch_after": "detection_mismatch_after",
    "heldout_evidence_before": "evidence_before",
    "heldout_evidence_after": "evidence_after",
    "reduction_interval_90": "pose_gap_reduction_interval_90",
    "stage": "kind",
}


def _scored_record(record: dict[str, Any], keep: tuple[str, ...]) -> dict[str, Any]:
    """A schema-1 record with its scores (the keys not in ``keep``) renamed under ``scores``."""
    scores = {_V1_RANKED.get(k, k): v for k, v in record.items() if k not in keep}
    return {_V1_RANKED.get(k, k): record[k] for k in keep if k in record} | {"scores": scores}


def upgrade_v1(data: dict[str, Any]) -> dict[str, Any]:
    """Schema-1 ``result.json`` data in the schema-2 layout (:func:`upgrade_v2` lifts it on).

    Renamed: ``split.train`` / ``split.heldout`` (``fit`` / ``choose``), ``where.axes``
    (``axis_gaps``) with ``z_mean`` (``z_median``), a region's ``mean`` (``median``), the
    ``heldout_*`` scores of ``ranking``, ``combined``, ``confirmed`` and
    ``combined.equivalent_models`` (:data:`_V1_RANKED`). Moved: ``combined.effects``,
    ``n_params``, ``choice`` and ``equivalent_models`` to ``selection``.
    """
    out = {k: v for k, v in data.items() if k not in DiagnosisResult.json_derived}
    out["schema_version"] = 2
    where = dict(data.get("where", {}))
    if "axes" in where:
        where["axis_gaps"] = {
            axis: {("z_median" if k == "z_mean" else k): v for k, v in gap.items()}
            for axis, gap in where.pop("axes").items()
        }
    where["regions"] = [
        {("median" if k == "mean" else k): v for k, v in r.items()}
        for r in where.get("regions", [])
    ]
    out["where"] = where
    ranked = ("effect", "params", "n_params", "stage", "fit_seconds")
    out["ranking"] = [_scored_record(r, ranked) for r in data.get("ranking", [])]
    if "split" in data:
        s = data["split"]
        out["split"] = {"fit": s["train"], "choose": s["heldout"]} | {
            k: s[k] for k in ("report", "seed") if k in s
        }
    combined = data.get("combined")
    if combined is not None:
        choice = combined.get("choice", {})
        out["selection"] = {
            "findings": combined.get("effects", []),
            "n_params": combined.get("n_params"),
            "configurations": choice.get("configurations"),
            "scores": _scored_record(choice, ("configurations",))["scores"],
            "equivalent_models": [
                _scored_record(m, ("effects", "n_params"))
                for m in combined.get("equivalent_models", [])
            ],
        }
        moved = ("effects", "n_params", "choice", "equivalent_models", "measured_on")
        kept = ("configurations", "reduction_interval_90", "evidence_reduction_interval_90")
        rest = {k: v for k, v in combined.items() if k not in moved}
        out["combined"] = _scored_record(rest, kept)
    if data.get("confirmed") is not None:
        out["confirmed"] = {_V1_RANKED.get(k, k): v for k, v in data["confirmed"].items()}
    return out


def upgrade_v2(data: dict[str, Any]) -> dict[str, Any]:
    """Schema-2 ``result.json`` data in the schema-3 layout.

    Renamed (:data:`_V2_RENAMED`, :data:`_V2_DETECTION`): ``split.report`` (``split.measure``)
    and the counts of items, ``where.comparable_configurations`` (``where.comparable_items``),
    ``where.detection.visible_configurations`` (``visible_items``) and the ``configurations`` of
    ``selection``, ``combined`` and ``confirmed`` (``items``).
    """
    out = dict(data, schema_version=3)
    for key, names in _V2_RENAMED.items():
        if out.get(key) is not None:
            out[key] = _renamed(out[key], names)
    detection = out.get("where", {}).get("detection")
    if detection is not None:
        out["where"] = out["where"] | {"detection": _renamed(detection, _V2_DETECTION)}
    return out


#: Schema 2 keys renamed in schema 3, per top-level record of ``result.json``.
_V2_RENAMED = {
    "split": {"report": "measure"},
    "where": {"comparable_configurations": "comparable_items"},
    "selection": {"configurations": "items"},
    "combined": {"configurations": "items"},
    "confirmed": {"configurations": "items"},
}
#: Schema 2 keys of ``where.detection`` renamed in schema 3.
_V2_DETECTION = {"visible_configurations": "visible_items"}


def _renamed(record: dict[str, Any], names: dict[str, str]) -> dict[str, Any]:
    """``record`` with its keys renamed by ``names``."""
    return {names.get(k, k): v for k, v in record.items()}


@dataclass(kw_only=True)
class DiagnosisResult(VersionedRecord):
    """The whole diagnosis (``result.json``); see the module docstring.

    ``selected``, ``minor`` and ``unexplained`` follow from the others (written to
    ``result.json`` for readers, never read back). :meth:`to_json` and :meth:`from_json` write
    and read ``result.json`` data of schema 3, and read schemas 2 (:func:`upgrade_v2`) and 1
    (:func:`upgrade_v1`, then :func:`upgrade_v2`).
    """

    json_derived: ClassVar[tuple[str, ...]] = ("selected", "minor", "unexplained")
    json_schema = SCHEMA_VERSION
    json_upgrades = {1: upgrade_v1, 2: upgrade_v2}
    json_source = "result.json"

    schema_version: int = SCHEMA_VERSION
    where: Where = field(default_factory=Where)
    #: every candidate alone, best first
    ranking: list[RankedEffect] = field(default_factory=list)
    #: candidates whose fit put a parameter on the end of its searched range: not findings
    #: (:func:`simgap.analysis.search.at_bound`), listed for the engineer
    on_bound: list[RankedEffect] = field(default_factory=list)
    #: None when nothing is selected
    selection: Selection | None = None
    #: the model with geometry the search refused because it left the corners more than
    #: :data:`~simgap.analysis.thresholds.GEOMETRY_CORNER_GAP_PX` off (None: none refused)
    refused_geometry: EquivalentModel | None = None
    #: significant evidence the chosen model leaves unexplained: "pose", "detection",
    #: "scatter", "corners" (geometry refused) or an image statistic
    unexplained_evidence: list[str] = field(default_factory=list)
    split: Split | None = None
    #: render seeds per configuration of the simulation
    render_seeds: int = 1
    #: how the simulation was rendered: ``render.mode`` and samples per pixel, e.g. "path 16 spp"
    simulation_render: str = ""
    #: the capture's demosaicing, simulated with it; None where its frames show none
    demosaicing: Demosaicing | None = None
    #: whether the capture was ingested with its camera's measured response (``ingest
    #: --response``): its levels read through it and the simulation imaged through it
    measured_response: bool = False
    #: what the capture and the simulation show of each stage of a camera's own pipeline
    camera_pipeline: list[PipelineSignature] = field(default_factory=list)
    #: the marker sizes' change split into a share and an edge offset; None where fewer than
    #: four tags or no spread of sizes (absent in files written before it)
    edge_offset: EdgeOffset | None = None
    #: corner noise (px per coordinate) propagated through PnP to each item's pose
    #: noise, where the simulation's repeats measure none (a converged render); None otherwise
    propagated_corner_noise_px: float | None = None
    #: corner noise (px per coordinate of one frame) of the capture beyond the simulation's,
    #: whose pose shift moved each converged simulated pose
    #: (:func:`simgap.diagnosis.items.with_noise_shift`); None where path traced
    noise_shift_corner_px: float | None = None
    combined: Combined | None = None
    confirmed: Confirmed | None = None
    seconds: float = 0.0

    @property
    def simulation_mode(self) -> str:
        """The simulation's ``render.mode`` (``converged`` or ``path``; empty where unrecorded)."""
        return self.simulation_render.split(" ")[0]

    @property
    def selected(self) -> list[str]:
        """The selected effects, most important first."""
        return [f.effect for f in self.selection.findings] if self.selection else []

    @property
    def minor(self) -> list[str]:
        """The selected effects that move no pose beyond the floor."""
        return [f.effect for f in self.selection.findings if f.minor] if self.selection else []

    def selected_on_bound(self) -> list[str]:
        """``effect.parameter`` of every selected parameter fitted on the end of its range."""
        findings = self.selection.findings if self.selection else []
        return [f"{f.effect}.{name}" for f in findings for name in f.at_bound]

    @property
    def unexplained(self) -> bool:
        """Some significant evidence is left unexplained."""
        return bool(self.unexplained_evidence)


def per_axis(values: Any) -> dict[str, float]:
    """A (6,) per-axis array as ``{axis: value}``."""
    return dict(zip(AXES, map(float, values), strict=True))
