"""kill -9 during saves: the persistence file is always valid JSON that restores, and the next
start leaves no temporary file (the 1,000-kill run: ``python -m
tire_estimation.evaluation.persistence_kill --kills 1000``)."""

from __future__ import annotations

import json
from pathlib import Path

from tire_estimation.evaluation.persistence_kill import main, run


def test_kills_during_saves_leave_a_valid_file_and_no_temporary_files(tmp_path: Path) -> None:
    report = run(kills=20, seed=38, directory=tmp_path, max_delay_s=0.03)
    assert report.failures == []
    assert report.kills == report.valid_json == report.restored == 20
    assert report.temps_after_restore == 0
    # the kills hit writes in progress (else the test would test nothing)
    assert report.temps_left_by_kill >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "learned_estimates.json",
        "state_to_write.json",
    ]


def test_the_command_prints_its_report(tmp_path: Path, capsys) -> None:
    assert main(["--kills", "2", "--seed", "1", "--dir", str(tmp_path)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] and out["kills"] == 2 and out["restored"] == 2
