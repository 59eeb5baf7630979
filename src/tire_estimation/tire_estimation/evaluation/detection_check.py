"""The replay's deflation warning on simulated drives of the validated length.

A drive with a 20 % pressure step on one rear wheel after the detector's default calibration
(20 min of driving at 40-120 km/h) must give the alarm on that wheel within 10 min of the step
(ECE R-64); a drive without deflation must give none. Each drive is simulated, written as a
bag and replayed with the default configuration (the stiffness MPF left out: it does not feed
the detector), exactly as ``tire-estimation replay`` does.

    python -m tire_estimation.evaluation.detection_check --out DIR [--seeds 0 1 ...]

Writes ``DIR/summary.json`` and prints one line per drive; exit status 1 when a check fails.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tire_estimation.atomic_io import atomic_write_text

#: the deadline of an alarm after the step, s (ECE R-64)
DEADLINE_S = 600.0


def _drive(scenario: str, seed: int, minutes: float, out: Path, **options: Any) -> Path:
    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.sim import simulate

    bag = out / f"{scenario}_{seed}"
    write_sim_bag(simulate(scenario, seed=seed, minutes=minutes, **options), bag)
    return bag


def check_step(seed: int, out: Path, wheel: str = "wheel_rl") -> dict[str, Any]:
    """40 min with a 20 % step on ``wheel`` at 25 min: the first alarm names it within 10 min."""
    from tire_estimation.replay import run_replay

    step_s = 25 * 60.0
    bag = _drive(
        "ece_r64", seed, 40.0, out, deflate_wheel=wheel, deflation_fraction=0.2,
        deflation_time_min=step_s / 60.0,
    )  # fmt: skip
    metrics = run_replay(bag, out / f"{bag.name}_report", stiffness=False, progress=False).metrics
    det = metrics["detection"]
    alarms = det["alarms"]
    delay = alarms[0]["t_s"] - step_s if alarms else None
    ok = bool(
        alarms and alarms[0]["wheel"] == wheel and delay is not None and 0.0 <= delay <= DEADLINE_S
    )
    return {
        "drive": bag.name,
        "kind": "step",
        "wheel": wheel,
        "step_s": step_s,
        "alarms": alarms,
        "delay_s": delay,
        "armed": det["armed"],
        "ok": ok,
    }


def check_clean(seed: int, out: Path) -> dict[str, Any]:
    """60 min without deflation: no alarm."""
    from tire_estimation.replay import run_replay

    bag = _drive("robustness", seed, 60.0, out)
    metrics = run_replay(bag, out / f"{bag.name}_report", stiffness=False, progress=False).metrics
    det = metrics["detection"]
    worst = max(
        (w["max_cusum_over_threshold"] or 0.0 for w in det["wheels"].values()), default=0.0
    )
    return {
        "drive": bag.name,
        "kind": "clean",
        "alarms": det["alarms"],
        "armed": det["armed"],
        "max_cusum_over_threshold": worst,
        "ok": det["armed"] and not det["alarms"],
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the checks, print and write the summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="directory for bags and reports")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="simulation seeds")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for seed in args.seeds:
        for check in (check_step, check_clean):
            t0 = time.perf_counter()
            row = check(seed, args.out)
            row["wall_s"] = time.perf_counter() - t0
            rows.append(row)
            alarms = ", ".join(f"{a['wheel']} at {a['t_s']:.0f} s" for a in row["alarms"])
            print(
                f"{row['drive']}: {'ok' if row['ok'] else 'FAILED'} "
                f"(alarms: {alarms or 'none'}; armed {row['armed']}; {row['wall_s']:.0f} s)"
            )
    atomic_write_text(args.out / "summary.json", json.dumps(rows, indent=2))
    return 0 if all(r["ok"] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
