"""result.json as typed records: schema 3 written and read back, schemas 2 and 1 still read."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from simgap.diagnosis.result import SCHEMA_VERSION, DiagnosisResult

#: sample-focal's result.json as simgap wrote it before schema 2 (commit 23f6bf2)
V1 = Path(__file__).parent / "data" / "result_v1_sample_focal.json"
#: sample-focal's result.json as simgap wrote it in schema 2 (commit f0cf48a)
V2 = Path(__file__).parent / "data" / "result_schema2.json"


def test_schema_1_is_read_under_the_new_names():
    raw = json.loads(V1.read_text())
    result = DiagnosisResult.from_json(raw)
    assert result.schema_version == SCHEMA_VERSION == 3
    # what the old file said, read through the new names (values copied from the file)
    assert result.selected == raw["selected"] == ["focal_length", "blur", "exposure"]
    assert result.minor == raw["minor"] == ["exposure"]
    assert result.unexplained is raw["unexplained"] is True
    assert (result.split.fit, result.split.choose, result.split.measure) == (4, 2, 3)
    assert result.where.axis_gaps["ty"].z_median == raw["where"]["axes"]["ty"]["z_mean"]
    assert result.where.regions[0].median == raw["where"]["regions"][0]["mean"]
    top = raw["ranking"][0]
    assert result.ranking[0].scores.pose_gap_after == top["heldout_gap_after"]
    assert result.ranking[0].kind == top["stage"] == "projection"
    combined = raw["combined"]
    assert result.selection.findings[0].params == combined["effects"][0]["params"]
    assert result.selection.items == combined["choice"]["configurations"] == 2
    assert result.combined.scores.pose_gap_reduction == combined["reduction"]
    assert list(result.combined.pose_gap_reduction_interval_90) == combined["reduction_interval_90"]
    assert result.combined.scores.median_abs_gap_after == combined["heldout_gap_after_per_axis"]
    assert result.confirmed.pose_gap_reduction == raw["confirmed"]["reduction"]


def test_schema_2_is_read_under_the_new_names():
    raw = json.loads(V2.read_text())
    assert raw["schema_version"] == 2
    result = DiagnosisResult.from_json(raw)
    assert result.schema_version == SCHEMA_VERSION
    # what the old file said, read through the new names (values copied from the file)
    assert result.selected == raw["selected"] and result.selected[0] == "focal_length"
    split = raw["split"]
    assert (result.split.fit, result.split.choose, result.split.measure) == (
        split["fit"],
        split["choose"],
        split["report"],
    )
    assert result.combined.scores.pose_gap_reduction == raw["combined"]["scores"][
        "pose_gap_reduction"
    ]
    # counts of items were called configurations
    assert result.where.comparable_items == raw["where"]["comparable_configurations"] == 9
    detection = raw["where"]["detection"]
    assert result.where.detection.visible_items == detection["visible_configurations"]
    for name in ("selection", "combined", "confirmed"):
        assert getattr(result, name).items == raw[name]["configurations"], name
    assert result.combined.items == result.split.measure
    # nothing is lost between the schemas: the old file's numbers are the new one's, NaN too
    data = json.loads(json.dumps(result.to_json()))
    assert data["schema_version"] == 3
    new = {k: v for k, v in data.items() if k != "schema_version"}
    old = {k: v for k, v in raw.items() if k != "schema_version"}
    assert _numbers(old) == _numbers(new)
    assert json.dumps(old).count("NaN") == json.dumps(new).count("NaN")


def test_schema_3_round_trips_and_writes_the_derived_keys():
    result = DiagnosisResult.from_json(json.loads(V1.read_text()))
    data = json.loads(json.dumps(result.to_json()))
    assert data["schema_version"] == 3
    assert data["selected"] == result.selected and data["unexplained"] is True
    again = DiagnosisResult.from_json(data).to_json()
    assert json.dumps(again) == json.dumps(data)  # NaN for what schema 1 did not keep
    # nothing is lost between the schemas: the old file's numbers are the new one's
    new = {k: v for k, v in data.items() if k != "schema_version"}
    assert _numbers(json.loads(V1.read_text())) == _numbers(new)


def _numbers(tree) -> list[float]:
    """Every number of a JSON tree but NaN, sorted (the key names aside)."""
    if isinstance(tree, dict):
        return sorted(v for item in tree.values() for v in _numbers(item))
    if isinstance(tree, list):
        return sorted(v for item in tree for v in _numbers(item))
    number = isinstance(tree, (int, float)) and not isinstance(tree, bool)
    return [float(tree)] if number and tree == tree else []


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d["where"]["axis_gaps"]["ty"].update(n="nine"), r"where\.axis_gaps\.ty\.n"),
        (lambda d: d["split"].pop("choose"), r"split: missing key 'choose'"),
        (lambda d: d["combined"].update(reduction=0.5), r"combined: unexpected key\(s\) reduction"),
        (lambda d: d.update(schema_version=4), r"schema_version: expected 1, 2 or 3, got 4"),
    ],
)
def test_a_result_that_does_not_fit_the_schema_names_the_key(change, message):
    data = DiagnosisResult.from_json(json.loads(V1.read_text())).to_json()
    change(data)
    with pytest.raises(ValueError, match=message):
        DiagnosisResult.from_json(data, "diag/result.json")


def test_refused_geometry_round_trips_and_is_named_in_the_report():
    """A model with geometry refused for the corners it leaves is kept and said in words."""
    from simgap.diagnosis.diagnosis_report import which_markdown
    from simgap.diagnosis.result import EquivalentModel

    result = DiagnosisResult.from_json(json.loads(V1.read_text()))
    assert result.refused_geometry is None  # schema 1 and results without one read as none
    # blind seed 35 trial 72's camera mount: 1.185 px of the corners left on the choose split
    scores = dataclasses.replace(result.selection.scores, corner_gap_after_px=1.185)
    result.refused_geometry = EquivalentModel(effects=["camera_mount"], n_params=6, scores=scores)
    data = json.loads(json.dumps(result.to_json()))
    again = DiagnosisResult.from_json(data)
    assert json.dumps(again.to_json()) == json.dumps(data)
    assert again.refused_geometry.effects == ["camera_mount"]
    text = "\n".join(which_markdown(again))
    assert (
        "Geometry left out: the best model with it (camera_mount) leaves the detected "
        "corners 1.19 px off (more than 0.8 px)" in text
    )
