"""Kill a process that saves learned estimates in a loop, many times at random moments, and
check the persistence file after every kill.

    python -m tire_estimation.evaluation.persistence_kill --kills 1000 --seed 0

Each round starts a writer process (``--write``) that saves a real estimator state (radius and
stiffness estimators of the default vehicle, one value changed per save) in a loop through
:func:`~tire_estimation.persistence.save_state`, kills it with SIGKILL after a random delay
(seeded), and then does what a node does at start, :func:`~tire_estimation.persistence.restore`.
A round passes when the file is valid JSON, every part restores, and no temporary file is left
after the restore. Prints a JSON report; exit status 1 when a round failed.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.atomic_io import atomic_write_text, temp_pattern
from tire_estimation.persistence import Identity, LearnedState, read_json, restore, save_state

IDENTITY = Identity("kill_test_vehicle", "kill_test_tires")
MODULE = "tire_estimation.evaluation.persistence_kill"


@dataclass
class KillReport:
    """Counts over the rounds.

    Attributes:
        kills: writer processes killed.
        valid_json: rounds whose file read back as JSON.
        restored: rounds whose every part restored.
        temps_left_by_kill: rounds after whose kill a temporary file was there (the kill hit a
            write between the creation of the temporary file and the rename).
        temps_after_restore: temporary files left after the restores (summed).
        max_delay_s: largest delay between the writer's first save and its kill, s.
        wall_s: duration of the run, s.
        failures: what went wrong in the failed rounds (at most 20).
    """

    kills: int = 0
    valid_json: int = 0
    restored: int = 0
    temps_left_by_kill: int = 0
    temps_after_restore: int = 0
    max_delay_s: float = 0.0
    wall_s: float = 0.0
    failures: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """Every round passed."""
        return not self.failures and self.restored == self.kills


def _estimators() -> LearnedState:
    """The radius and stiffness estimators of the default vehicle, few particles."""
    from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
    from tire_estimation.core.vehicle import VehicleParams

    pipeline = EstimationPipeline(
        PipelineConfig(
            seed=0,
            radius=RadiusEstimatorConfig(n_particles=50),
            stiffness=StiffnessEstimatorConfig(n_particles=20),
        ),
        VehicleParams(name=IDENTITY.vehicle_name),
    )
    return LearnedState({"radius": pipeline.radius, "stiffness": pipeline.stiffness})


def write_forever(path: Path, state_file: Path) -> None:
    """The writer: save the state in ``state_file`` to ``path`` in a loop (until killed),
    the first rear radius error changing by 1 um per save; prints ``ready`` after the first."""
    state: dict[str, Any] = json.loads(state_file.read_text())
    mean = state["radius"]["rear"]["mean_m"]
    n = 0
    while True:
        mean[0] = 1e-6 * (n % 1000)
        save_state(path, IDENTITY, state)
        if n == 0:
            print("ready", flush=True)
        n += 1


def _temps(path: Path) -> list[Path]:
    pattern = temp_pattern(path)
    return [p for p in path.parent.iterdir() if pattern.fullmatch(p.name)]


def run(kills: int, seed: int, directory: Path, max_delay_s: float = 0.05) -> KillReport:
    """``kills`` rounds (module docstring) in ``directory``; delays uniform in
    ``[0, max_delay_s]`` drawn from ``np.random.default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    report = KillReport(max_delay_s=max_delay_s)
    target = _estimators()
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / "learned_estimates.json"
    state_file = directory / "state_to_write.json"
    atomic_write_text(state_file, json.dumps(target.state_dict()))
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    t0 = time.perf_counter()
    for k in range(kills):
        writer = subprocess.Popen(
            [sys.executable, "-m", MODULE, "--write", str(path), "--state", str(state_file)],
            stdout=subprocess.PIPE,
            env=env,
        )
        assert writer.stdout is not None
        ready = writer.stdout.readline().strip() == b"ready"
        time.sleep(float(rng.uniform(0.0, max_delay_s)))
        writer.send_signal(signal.SIGKILL)
        writer.wait()
        writer.stdout.close()
        report.kills += 1
        if not ready:
            report.failures.append(f"round {k}: the writer did not start")
            continue
        report.temps_left_by_kill += bool(_temps(path))
        try:
            read_json(path)
        except (OSError, ValueError) as exc:
            report.failures.append(f"round {k}: not valid JSON: {exc}")
        else:
            report.valid_json += 1
        outcome = restore(path, IDENTITY, target, "estimates")
        if outcome.rejected or set(target.notes.values()) != {"restored"}:
            report.failures.append(f"round {k}: {outcome.note}")
        else:
            report.restored += 1
        left = _temps(path)
        report.temps_after_restore += len(left)
        if left:
            report.failures.append(f"round {k}: temporary files left: {[p.name for p in left]}")
        del report.failures[20:]
    report.wall_s = time.perf_counter() - t0
    return report


def main(argv: Sequence[str] | None = None) -> int:
    """Command line (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kills", type=int, default=1000, help="writer processes to kill")
    parser.add_argument("--seed", type=int, default=0, help="seed of the kill delays")
    parser.add_argument(
        "--max-delay-s", type=float, default=0.05, help="largest delay before a kill, s"
    )
    parser.add_argument("--dir", type=Path, default=None, help="work directory (default: temp)")
    parser.add_argument("--write", type=Path, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--state", type=Path, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.write is not None:
        write_forever(args.write, args.state)
        return 0
    with tempfile.TemporaryDirectory(prefix="persistence_kill_") as tmp:
        report = run(args.kills, args.seed, args.dir or Path(tmp), args.max_delay_s)
    print(json.dumps({**asdict(report), "ok": report.ok}, indent=1))
    return 0 if report.ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
