"""``replay --rank-effects --write-config``: the effect in the residuals is added to the model,
written as a params file that the replay and the node load, with the fit before and after."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tire_estimation.cli import main

#: estimator settings of the injection tests (tests/evaluation/test_residuals.py): this
#: drive's GNSS error is white and the filter is told so
RADIUS = {
    "n_particles": 200,
    "init_min_distance_m": 50.0,
    "prior_radius_error_std_m": 1e-3,
    "gnss_bias_fraction": 0.0,
    "gnss_velocity_enabled": False,
}


@pytest.mark.slow
def test_an_injected_gnss_latency_is_found_sized_and_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = tmp_path / "bag"
    argv = ["simulate", "robustness", "--seed", "251", "--minutes", "2", "--out", str(bag)]
    argv += ["--sensor", "gnss_latency_s=0.2", "--sensor", "gnss_velocity_enabled=false"]
    assert main(argv) == 0
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump({"stiffness_enabled": False, "radius": RADIUS}))
    written = tmp_path / "closed.yaml"
    out = tmp_path / "report"
    argv = ["replay", str(bag), "--out", str(out), "--config", str(cfg), "--no-plots"]
    assert main([*argv, "--no-progress", "--rank-effects", "--write-config", str(written)]) == 0
    loop = json.loads((out / "metrics.json").read_text())["closed_loop"]
    first = loop["effects"][0]
    assert first["effect"] == "gnss_latency" and first["field"] == "gnss_latency_s"
    assert 0.1 < first["estimate"] < 0.3
    assert loop["after"]["neg_log_likelihood"] < loop["before"]["neg_log_likelihood"]
    assert loop["after"]["position_rmse_m"] < loop["before"]["position_rmse_m"]
    params = yaml.safe_load(written.read_text())["estimator_node"]["ros__parameters"]
    assert params["radius.gnss_latency_s"] == pytest.approx(first["estimate"])
    assert params["radius.n_particles"] == 200  # the run's own settings come along
    assert "closed loop: gnss_latency" in capsys.readouterr().out
    # the written file alone reproduces the "after" run
    again = tmp_path / "again"
    argv = ["replay", str(bag), "--out", str(again), "--config", str(written), "--no-plots"]
    assert main([*argv, "--no-progress", "--no-stiffness"]) == 0
    radii = json.loads((again / "metrics.json").read_text())["radii"]["final_radius_error_m"]
    assert radii == pytest.approx(loop["after"]["final_radius_error_m"], abs=1e-12)


def test_write_config_needs_the_ranking(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = Path(__file__).resolve().parents[1] / "bags" / "comma2k19_rav4_seg40"
    argv = [
        "replay",
        str(bag),
        "--out",
        str(tmp_path / "o"),
        "--write-config",
        str(tmp_path / "c"),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs rank_effects" in err[0]
    assert not (tmp_path / "c").exists()
