"""The blind validation's report from a fixed set of trials: the same scores, the same markdown.

The data files were written once by the code before the trial scores were typed (commit
081b3d4), from 26 trials on seed 58's drawn other cameras with hand-written diagnoses: pairs
(found, half found, missed), no-effect trials (clean, the camera's own effects, a spurious
laminate, a spurious print scale), motion blur (unexplained, and answered with geometry),
blur-only trials, JPEG behind crushed blacks, a parameter on its bound, a capture whose blacks
were not measured and a trial without a drawn camera.

- ``validation_trials_v1.json``: the trials as ``OUTPUT/trials/trial_NNN.json`` kept them;
- ``validation_summary_v1.json``: their summary as ``validation.json`` kept it;
- ``validation_golden.md``: their ``validation.md``.
"""

from __future__ import annotations

import json
from pathlib import Path

from simgap.core.rig import load_rig
from simgap.diagnosis.nuisance import NuisanceCamera
from simgap.diagnosis.result import DiagnosisResult
from simgap.diagnosis.trial import Trial
from simgap.diagnosis.validation_report import summarize_scores, validation_markdown

DATA = Path(__file__).parent / "data"
TRIALS_V1 = DATA / "validation_trials_v1.json"
SUMMARY_V1 = DATA / "validation_summary_v1.json"
GOLDEN_MD = DATA / "validation_golden.md"
#: trials planned in the run the golden report is the summary of
TRIALS_PLANNED = 30
#: the keys of a trial file that are not its score
RECORD_KEYS = ("index", "crushed_black", "params", "camera", "result", "seconds")


def _rescored(record: dict) -> Trial:
    """The trial a kept record was made of: its draws, camera, diagnosis and capture."""
    camera = NuisanceCamera.from_record(record["camera"]) if record["camera"] else None
    result = DiagnosisResult.from_json(record["result"])
    rig = load_rig() if camera else None
    return Trial(
        record["index"], record["params"], camera, result, record["seconds"], rig,
        record["crushed_black"],
    )  # fmt: skip


def test_kept_trials_score_as_the_current_code_scores_them():
    for record in json.loads(TRIALS_V1.read_text()):
        score = {k: v for k, v in record.items() if k not in RECORD_KEYS}
        rescored = json.loads(json.dumps(_rescored(record).record()))
        assert {k: v for k, v in rescored.items() if k not in RECORD_KEYS} == score
        assert rescored == record


def test_the_summary_and_the_markdown_are_the_golden_ones():
    records = json.loads(TRIALS_V1.read_text())
    summary = summarize_scores(records)
    summary["trials_planned"] = TRIALS_PLANNED
    assert json.loads(json.dumps(summary)) == json.loads(SUMMARY_V1.read_text())
    assert validation_markdown(summary, records) == GOLDEN_MD.read_text()
