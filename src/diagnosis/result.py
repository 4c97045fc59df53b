"""The diagnosis's result as typed records: where, ranking, selection, combined, confirmed.

:class:`DiagnosisResult` is what :func:`simgap.diagnosis.diagnose.diagnose` returns and what
``result.json`` holds (:meth:`DiagnosisResult.to_json`, :meth:`DiagnosisResult.from_json`; the
README documents the schema). Three splits of the comparable configurations, one name each:
*fit* (the effects' parameters are fitted), *choose* (models are ranked, combined, simplified and
pruned: :class:`RankedEffect`, :class:`Selection`) and *report* (the chosen model is measured:
:class:`Combined`, :class:`Confirmed`).

Schema versions: 2 (this one); 1 (no ``schema_version`` key: the splits were ``train`` /
``heldout`` / ``report`` and most scores had a ``heldout_`` prefix whatever their split) is still
read (:func:`upgrade_v1`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

from simgap.analysis.channels import root_sum_square
from simgap.analysis.evidence import DetectionTest, ImageTest, ScatterTest
from simgap.analysis.gap import AxisGap, DetectionRates, RegionGap
from simgap.analysis.scored import Scored
from simgap.core.axes import AXES
from simgap.diagnosis.result_json import from_jsonable, jsonable

#: Version of the ``result.json`` schema written.
SCHEMA_VERSION = 2


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
    comparable_configurations: int = 0


@dataclass(kw_only=True)
class RankedEffect:
    """One candidate alone, fitted on the fit split and scored on the choose split.

    Each score is given before (the simulation alone) and after (with the effect); see
    :class:`simgap.analysis.scored.Scored` for their units. ``median_abs_gap_*`` are per axis
    (m or rad), ``image_misfit_*`` the root sum of squares over the image statistics (floors).
    """

    effect: str
    params: dict[str, Any]
    n_params: int
    kind: str
    pose_gap_before: float
    pose_gap_after: float
    pose_gap_reduction: float
    pose_gap_all_axes_before: float
    pose_gap_all_axes_after: float
    corner_gap_before_px: float
    corner_gap_after_px: float
    median_abs_gap_before: dict[str, float]
    median_abs_gap_after: dict[str, float]
    image_misfit_before: float
    image_misfit_after: float
    detection_mismatch_before: float
    detection_mismatch_after: float
    evidence_before: float
    evidence_after: float
    fit_seconds: float


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
        (:meth:`simgap.analysis.selection.ModelSearch.contributions`).
    minor : bool
        Seen in the corners or images, moves no pose beyond the floor.
    """

    effect: str
    params: dict[str, Any]
    pose_contribution: float
    minor: bool


@dataclass(kw_only=True)
class EquivalentModel:
    """A model tried that the choose split cannot tell from the chosen one."""

    effects: list[str]
    n_params: int
    corner_gap_after_px: float
    evidence_after: float
    pose_gap_after: float


@dataclass(kw_only=True)
class Selection:
    """The chosen model: its findings (most important first) and its scores on the choose split."""

    findings: list[Finding]
    n_params: int
    #: configurations of the choose split
    configurations: int
    evidence_before: float
    evidence_after: float
    pose_gap_after: float
    equivalent_models: list[EquivalentModel] = field(default_factory=list)


@dataclass(kw_only=True)
class Combined:
    """The chosen model measured on the report split (neither fitted nor chose it).

    Intervals are 90 % bootstrap intervals ([low, high]) of the reductions.
    """

    configurations: int
    pose_gap_before: float
    pose_gap_after: float
    pose_gap_reduction: float
    pose_gap_reduction_interval_90: tuple[float, float]
    corner_gap_before_px: float
    corner_gap_after_px: float
    evidence_before: float
    evidence_after: float
    evidence_reduction: float
    evidence_reduction_interval_90: tuple[float, float]
    median_abs_gap_before: dict[str, float]
    median_abs_gap_after: dict[str, float]


@dataclass(kw_only=True)
class Confirmed:
    """The report split re-run through the full pipeline (re-rendered) with the fitted effects."""

    configurations: int
    pose_gap_after: float
    pose_gap_reduction: float
    median_abs_gap_after: dict[str, float]
    seconds: float


@dataclass(kw_only=True)
class Split:
    """Sizes of the fit, choose and report splits, and the seed that drew them."""

    fit: int
    choose: int
    report: int
    seed: int


@dataclass(kw_only=True)
class DiagnosisResult:
    """The whole diagnosis (``result.json``); see the module docstring.

    ``selected``, ``minor`` and ``unexplained`` follow from the others (written to
    ``result.json`` for readers, never read back).
    """

    json_derived: ClassVar[tuple[str, ...]] = ("selected", "minor", "unexplained")

    schema_version: int = SCHEMA_VERSION
    where: Where = field(default_factory=Where)
    #: every candidate alone, best first
    ranking: list[RankedEffect] = field(default_factory=list)
    #: None when nothing is selected
    selection: Selection | None = None
    #: significant evidence the chosen model leaves unexplained: "pose", "detection",
    #: "scatter" or an image statistic
    unexplained_evidence: list[str] = field(default_factory=list)
    split: Split | None = None
    #: render seeds per configuration of the simulation
    render_seeds: int = 1
    combined: Combined | None = None
    confirmed: Confirmed | None = None
    seconds: float = 0.0

    @property
    def selected(self) -> list[str]:
        """The selected effects, most important first."""
        return [f.effect for f in self.selection.findings] if self.selection else []

    @property
    def minor(self) -> list[str]:
        """The selected effects that move no pose beyond the floor."""
        return [f.effect for f in self.selection.findings if f.minor] if self.selection else []

    @property
    def unexplained(self) -> bool:
        """Some significant evidence is left unexplained."""
        return bool(self.unexplained_evidence)

    def to_json(self) -> dict[str, Any]:
        """The plain-JSON form of ``result.json``."""
        return jsonable(self)

    @classmethod
    def from_json(cls, data: dict[str, Any], source: str = "result.json") -> DiagnosisResult:
        """Read ``result.json`` data of schema 2, or of schema 1 (:func:`upgrade_v1`).

        Raises
        ------
        ValueError
            Naming ``source`` and the key that does not fit the schema.
        """
        if not isinstance(data, dict):
            raise ValueError(f"{source}: expected a mapping, got {type(data).__name__}")
        version = data.get("schema_version", 1)
        if version == 1:
            data = upgrade_v1(data)
        elif version != SCHEMA_VERSION:
            raise ValueError(
                f"{source}: schema_version: expected 1 or {SCHEMA_VERSION}, got {version!r}"
            )
        return from_jsonable(cls, data, source)


def ranked_effect(scored: Scored) -> RankedEffect:
    """The ranking entry of a single-effect model scored on the choose split."""
    cand, fit = scored.fits[0]
    return RankedEffect(
        effect=fit.effect,
        params=fit.params,
        n_params=cand.n_params,
        kind=cand.kind,
        pose_gap_before=scored.pose_gap_before,
        pose_gap_after=scored.pose_gap_after,
        pose_gap_reduction=scored.pose_gap_reduction,
        pose_gap_all_axes_before=scored.pose_gap_all_axes_before,
        pose_gap_all_axes_after=scored.pose_gap_all_axes_after,
        corner_gap_before_px=scored.corner_gap_before_px,
        corner_gap_after_px=scored.corner_gap_after_px,
        median_abs_gap_before=per_axis(scored.median_abs_gap_before),
        median_abs_gap_after=per_axis(scored.median_abs_gap_after),
        image_misfit_before=root_sum_square(scored.image_misfit_before),
        image_misfit_after=root_sum_square(scored.image_misfit_after),
        detection_mismatch_before=scored.detection_mismatch_before,
        detection_mismatch_after=scored.detection_mismatch_after,
        evidence_before=scored.evidence_before,
        evidence_after=scored.evidence_after,
        fit_seconds=fit.seconds,
    )


def per_axis(values: Any) -> dict[str, float]:
    """A (6,) per-axis array as ``{axis: value}``."""
    return dict(zip(AXES, map(float, values), strict=True))


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


def _renamed(record: dict[str, Any], drop: tuple[str, ...] = ()) -> dict[str, Any]:
    return {_V1_RANKED.get(k, k): v for k, v in record.items() if k not in drop}


def upgrade_v1(data: dict[str, Any]) -> dict[str, Any]:
    """Schema-1 ``result.json`` data in the schema-2 layout (read for one version).

    Renamed: ``split.train`` / ``split.heldout`` (``fit`` / ``choose``), ``where.axes``
    (``axis_gaps``) with ``z_mean`` (``z_median``), a region's ``mean`` (``median``), the
    ``heldout_*`` scores of ``ranking``, ``combined``, ``confirmed`` and
    ``combined.equivalent_models`` (:data:`_V1_RANKED`). Moved: ``combined.effects``,
    ``n_params``, ``choice`` and ``equivalent_models`` to ``selection``.
    """
    out = {k: v for k, v in data.items() if k not in DiagnosisResult.json_derived}
    out["schema_version"] = SCHEMA_VERSION
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
    out["ranking"] = [_renamed(r) for r in data.get("ranking", [])]
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
            "evidence_before": choice.get("heldout_evidence_before"),
            "evidence_after": choice.get("heldout_evidence_after"),
            "pose_gap_after": choice.get("heldout_gap_after"),
            "equivalent_models": [_renamed(m) for m in combined.get("equivalent_models", [])],
        }
        moved = ("effects", "n_params", "choice", "equivalent_models", "measured_on")
        out["combined"] = _renamed(combined, drop=moved)
    if data.get("confirmed") is not None:
        out["confirmed"] = _renamed(data["confirmed"])
    return out

