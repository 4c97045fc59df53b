"""The blind validation's report from a fixed set of trials: the same scores, the same markdown.

The data files were written once by the code before the trial scores were typed (commit
081b3d4), from 26 trials on seed 58's drawn other cameras with hand-written diagnoses: pairs
(found, half found, missed), no-effect trials (clean, the camera's own effects, a spurious
laminate, a spurious print scale), motion blur (unexplained, and answered with geometry),
blur-only trials, JPEG behind crushed blacks, a parameter on its bound, a capture whose blacks
were not measured and a trial without a drawn camera.

- ``validation_trials_v1.json``: the trials as ``OUTPUT/trials/trial_NNN.json`` kept them
  (trial schema 1);
- ``validation_summary_v1.json``: their summary as ``validation.json`` kept it (schema 1);
- ``validation_golden.md``: their ``validation.md``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from simgap.core.rig import load_rig
from simgap.diagnosis.result import upgrade_v2
from simgap.diagnosis.result_json import jsonable
from simgap.diagnosis.trial import Trial
from simgap.diagnosis.trial_score import TRIAL_SCHEMA_VERSION, TrialRecord
from simgap.diagnosis.validation_report import validation_json, validation_markdown
from simgap.diagnosis.validation_summary import summarize_scores

DATA = Path(__file__).parent / "data"
TRIALS_V1 = DATA / "validation_trials_v1.json"
SUMMARY_V1 = DATA / "validation_summary_v1.json"
GOLDEN_MD = DATA / "validation_golden.md"
#: trials planned in the run the golden report is the summary of
TRIALS_PLANNED = 30
#: schema-1 trial keys (the score's and the record's) under their schema-2 names
TRIAL_V1_NAMES = {
    "reduction": "pose_gap_reduction",
    "reduction_interval_90": "pose_gap_reduction_interval_90",
    "bins": "nuisance_bins",
    "crushed_black": "crushed_black_share",
}
#: schema-1 keys of a trial file that are the record's, not the score's
RECORD_V1 = ("index", "params", "camera", "result", "seconds")
#: the summary's shares of trials, Proportion records since schema 3 (docs/validation.md)
SHARES_OF_TRIALS = (
    "top1_accuracy", "every_effect_accuracy", "top1_accuracy_single",
    "top1_accuracy_appearance_single", "no_effect_correct", "no_effect_free_of_geometry",
    "blur_only_free_of_geometry", "jpeg_crushed_recall", "outside_unexplained", "spurious_share",
    "on_bound_share",
)  # fmt: skip
#: schema-1 summary keys under their schema-2 names (docs/validation.md)
SUMMARY_V1_NAMES = {
    "reduction_median": "pose_gap_reduction_median",
    "reduction_at_least_70pct": "pose_gap_reduction_at_least_70pct",
    "spurious_trials": "spurious_share",
    "on_bound_trials": "on_bound_share",
    "top1_single": "top1_accuracy_single",  # per effect
    "correct": "correct_trials",  # per nuisance bin
}


def _v1_trials() -> list[dict]:
    return json.loads(TRIALS_V1.read_text())


def _renamed(tree, names: dict[str, str]):
    """A JSON tree with its mapping keys renamed by ``names``."""
    if isinstance(tree, dict):
        return {names.get(k, k): _renamed(v, names) for k, v in tree.items()}
    return tree


def test_schema_1_trial_files_read_as_the_current_code_scores_them():
    """A kept trial file of schema 1 gives the score it holds, under the new names, and that
    score is the one the current code gives the trial it keeps (its draws, camera, diagnosis)."""
    rig = load_rig()
    for raw in _v1_trials():
        kept = TrialRecord.from_json(raw, f"trial_{raw['index']:03d}.json")
        assert kept.schema_version == TRIAL_SCHEMA_VERSION == 2
        # every number and name of the old file, read through the new names
        score = jsonable(kept.score)
        for key, value in raw.items():
            if key not in RECORD_V1:
                assert score[TRIAL_V1_NAMES.get(key, key)] == value, key
        assert set(score) - {TRIAL_V1_NAMES.get(k, k) for k in raw} <= {
            "recall", "magnitude_error", "pose_gap_reduction", "pose_gap_reduction_interval_90",
            "undecided",
        }  # fmt: skip
        assert kept.score.undecided == {}  # no finding was undecided when schema 1 was written
        if not kept.score.catalogue:  # schema 1 left these out: the defaults say "none"
            assert kept.score.recall is None and kept.score.magnitude_error == {}
        assert (kept.index, kept.seconds) == (raw["index"], raw["seconds"])
        assert jsonable(kept.hidden_params) == raw["params"]
        assert jsonable(kept.camera) == raw["camera"]
        # its diagnosis, a schema-2 result.json record, under the schema-3 names only
        assert raw["result"]["schema_version"] == 2
        expected = upgrade_v2(raw["result"])
        # added to schema 3 later: absent reads as none
        expected.setdefault("edge_offset", None)
        expected.setdefault("measured_response", False)
        for finding in (expected.get("selection") or {}).get("findings", []):
            finding.setdefault("look_alikes", [])
        assert kept.result.to_json() == expected
        trial = Trial(
            kept.index, kept.hidden_params, kept.camera, kept.result, kept.seconds,
            rig if kept.camera else None, kept.score.crushed_black_share,
        )  # fmt: skip
        assert trial.score() == kept.score
        assert json.dumps(trial.record().to_json()) == json.dumps(kept.to_json())


def test_schema_2_trial_files_round_trip():
    for raw in _v1_trials():
        kept = TrialRecord.from_json(raw)
        data = json.loads(json.dumps(kept.to_json()))
        assert data["schema_version"] == 2 and "score" in data and "params" not in data
        again = TrialRecord.from_json(data)
        assert again.score == kept.score
        assert json.dumps(again.to_json()) == json.dumps(data)


def test_the_markdown_is_the_golden_one_and_the_summary_keeps_its_numbers():
    """validation.md is the golden one, from trial files of either schema; validation.json's
    summary keeps every value of schema 1 (schema 2 renamed six keys; schema 3 holds each share
    of trials as a Proportion: the same share, with its counts and interval).

    The golden report's value column is byte for byte what the code before the typed summary
    wrote (git history of ``validation_golden.md``); the counts and intervals were added since.
    """
    trials = [TrialRecord.from_json(raw) for raw in _v1_trials()]
    summary = summarize_scores([t.score for t in trials], TRIALS_PLANNED)
    assert validation_markdown(summary, trials) == GOLDEN_MD.read_text()
    again = [TrialRecord.from_json(json.loads(json.dumps(t.to_json()))) for t in trials]
    assert validation_markdown(summary, again) == GOLDEN_MD.read_text()
    written = json.loads(json.dumps(validation_json(summary, trials)))
    assert written["schema_version"] == 3
    expected = _renamed(json.loads(SUMMARY_V1.read_text()), SUMMARY_V1_NAMES)
    # counted since findings can be undecided; none of these trials' findings is
    expected.update(undecided_trials=0, undecided_holding_hidden=0)
    got = written["summary"]
    # schema 3: the crushed-black JPEG trials are its proportion's trials
    assert got["jpeg_crushed_recall"]["trials"] == expected.pop("jpeg_crushed_trials") == 2
    for key in SHARES_OF_TRIALS:
        share = expected.pop(key)
        proportion = got.pop(key)
        assert proportion["share"] == pytest.approx(share), key
        assert proportion["count"] == round(share * proportion["trials"]), key
        low, high = proportion["interval_90"]
        assert low <= share <= high, key
    for name, effect in expected["per_effect"].items():
        single = got["per_effect"][name].pop("top1_accuracy_single")
        assert effect.pop("single_trials") == (single["trials"] if single else 0), name
        share = effect.pop("top1_accuracy_single")
        assert (single and single["share"]) == pytest.approx(share), name
    assert got == expected
    assert written["trials"] == [t.to_json() for t in trials]


def test_a_proportion_s_interval_is_the_exact_one():
    """Clopper-Pearson's 90 % interval, checked against its beta-quantile definition."""
    from scipy import stats

    from simgap.diagnosis.validation_summary import Proportion

    for count, trials in ((17, 20), (20, 20), (0, 2), (1, 26)):
        low, high = Proportion(count=count, trials=trials).interval_90
        want_low = stats.beta.ppf(0.05, count, trials - count + 1) if count else 0.0
        want_high = stats.beta.ppf(0.95, count + 1, trials - count) if count < trials else 1.0
        assert (low, high) == pytest.approx((want_low, want_high), abs=1e-9)
    # what a run of 20 can tell: 17 of 20 reaches from 66 % to 96 %; even 20 of 20 stays below
    # certainty of 90 %
    assert Proportion(count=17, trials=20).interval_90 == pytest.approx((0.656, 0.958), abs=1e-3)
    assert Proportion(count=20, trials=20).interval_90[0] == pytest.approx(0.861, abs=1e-3)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.update(schema_version=3), r"schema_version: expected 1 or 2, got 3"),
        (lambda d: d["score"].update(correct="yes"), r"trial_007\.json\.score\.correct"),
        (lambda d: d.pop("seconds"), r"trial_007\.json: missing key 'seconds'"),
        (lambda d: d["score"].update(reduction=0.5), r"score: unexpected key\(s\) reduction"),
        (lambda d: d["result"].update(schema_version=9), r"json\.result: schema_version"),
    ],
)
def test_a_trial_file_that_does_not_fit_the_schema_names_the_key(change, message):
    data = TrialRecord.from_json(_v1_trials()[7]).to_json()
    change(data)
    with pytest.raises(ValueError, match=message):
        TrialRecord.from_json(data, "trials/trial_007.json")


def test_a_run_resumes_from_a_schema_1_trial_file(tmp_path):
    """A trial file kept by a run before the typed scores is this run's trial, if its draws are
    the ones this run makes and it was diagnosed with the same simulation."""
    from simgap.diagnosis.validate import _kept_trial

    raw = _v1_trials()[3]
    path = tmp_path / "trials" / "trial_003.json"
    path.parent.mkdir()
    path.write_text(json.dumps(raw, indent=2))
    kept = TrialRecord.from_json(raw)
    assert kept.camera is not None
    assert _kept_trial(path, raw["params"], kept.camera, "converged") == kept
    with pytest.raises(ValueError, match="other hidden effects or another camera"):
        _kept_trial(path, {"blur": {"sigma_px": 1.0}}, kept.camera, "converged")
    with pytest.raises(ValueError, match="diagnosed with a converged simulation"):
        _kept_trial(path, raw["params"], kept.camera, "path")


def test_validate_ends_with_the_headline_counts_and_intervals(tmp_path, monkeypatch):
    """The command's last line: top-1 and no-effect trials as counts with their intervals."""
    from typer.testing import CliRunner

    import simgap.diagnosis.validate as validation
    from simgap.cli import app

    trials = [TrialRecord.from_json(raw) for raw in _v1_trials()]
    summary = summarize_scores([t.score for t in trials], TRIALS_PLANNED)

    def finished(exp, out_dir, cache_dir, settings, log, simulator):
        (out_dir / "validation.md").write_text(validation_markdown(summary, trials))
        return summary

    monkeypatch.setattr(validation, "run_validation", finished)
    args = ["validate", "experiments/smoke.yaml", "-o", str(tmp_path / "v"), "--no-progress"]
    result = CliRunner().invoke(app, args + ["--cache", str(tmp_path / "cache")])
    assert result.exit_code == 0, result.output
    # 14 of the 20 catalogue trials and 2 of the 4 no-effect ones (the golden report's rows)
    assert result.output.rstrip().endswith(
        "top-1 accuracy 14 of 20 (70%; 90% interval 49-86%), "
        "no-effect correct 2 of 4 (50%; 90% interval 10-90%)"
    )


def _run(folder: Path, raws: list[dict]) -> Path:
    """A validation run's folder keeping ``raws`` as its trial files."""
    (folder / "trials").mkdir(parents=True)
    for raw in raws:
        data = TrialRecord.from_json(raw).to_json()
        (folder / "trials" / f"trial_{raw['index']:03d}.json").write_text(json.dumps(data))
    return folder


def test_runs_pool_into_the_report_of_all_their_trials(tmp_path):
    """Two runs' trials pooled: the summary of all of them, each trial named by its run."""
    from simgap.diagnosis.validation_pool import write_pooled_report

    raws = _v1_trials()
    first, second = _run(tmp_path / "a", raws[:13]), _run(tmp_path / "b", raws[13:])
    summary = write_pooled_report([first, second], tmp_path / "pooled")
    trials = [TrialRecord.from_json(raw) for raw in raws]
    assert summary == summarize_scores([t.score for t in trials])
    assert summary.top1_accuracy is not None
    assert (summary.top1_accuracy.count, summary.top1_accuracy.trials) == (14, 20)
    written = json.loads((tmp_path / "pooled" / "validation.json").read_text())
    assert written["runs"] == [str(first), str(second)]
    assert [t["index"] for t in written["trials"]] == [raw["index"] for raw in raws]
    text = (tmp_path / "pooled" / "validation.md").read_text()
    assert (
        f"| {first}/{raws[0]['index']} | " in text and f"| {second}/{raws[13]['index']} | " in text
    )


def test_pooling_refuses_a_draw_kept_twice_and_runs_made_otherwise(tmp_path):
    from simgap.diagnosis.validation_pool import pooled_trials

    raws = _v1_trials()
    first = _run(tmp_path / "a", raws[:3])
    again = _run(tmp_path / "same_seed", raws[2:4])
    with pytest.raises(ValueError, match=r"same_seed/\d+: the same draw as .*a/\d+"):
        pooled_trials([first, again])
    other = json.loads(json.dumps(raws[5]))
    other["result"]["simulation_render"] = "path 16 spp"
    path_traced = _run(tmp_path / "path", [other])
    with pytest.raises(ValueError, match=r"path/\d+: diagnosed otherwise than .*a/\d+"):
        pooled_trials([first, path_traced])


def test_report_validation_names_a_folder_that_is_no_run(tmp_path):
    from typer.testing import CliRunner

    from simgap.cli import app

    run = _run(tmp_path / "a", _v1_trials()[:2])
    (tmp_path / "empty").mkdir()
    args = ["report-validation", str(run), str(tmp_path / "empty"), "-o", str(tmp_path / "p")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert "empty: no trials/trial_NNN.json; expected the output folder of simgap validate" in (
        result.output
    )
    assert not (tmp_path / "p").exists()  # nothing written, the folder taken back
