"""Peak memory of the replay against drive length (part of ``make bench``).

Each bag is replayed by ``tire-estimation replay BAG --out DIR --no-progress`` in a process of
its own, so that the peak resident set size the kernel reports for that process
(``wait4`` ``ru_maxrss``) is the replay's alone: interpreter, imports, the run and the report.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any


def replay_peak_rss(bag: Path, *, stiffness: bool = True, plots: bool = True) -> dict[str, Any]:
    """Replay ``bag`` in a child process; its peak RSS (MB), wall time and drive duration."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [
            sys.executable, "-m", "tire_estimation.cli", "replay", str(bag),
            "--out", out, "--no-progress",
        ]  # fmt: skip
        if not stiffness:
            cmd.append("--no-stiffness")
        if not plots:
            cmd.append("--no-plots")
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        assert proc.stderr is not None
        err = proc.stderr.read()
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        wall_s = time.perf_counter() - t0
        if proc.returncode != 0:
            text = err.decode(errors="replace").strip().splitlines()
            raise RuntimeError(f"replay of {bag} failed: {text[-1] if text else proc.returncode}")
        metrics = json.loads((Path(out) / "metrics.json").read_text())
    return {
        "bag": str(bag),
        "duration_s": float(metrics["duration_s"]),
        "wall_s": wall_s,
        # Linux reports ru_maxrss in KiB
        "peak_rss_mb": usage.ru_maxrss * 1024 / 1e6,
        "stiffness": stiffness,
        "plots": plots,
    }


def memory_against_length(bags: list[Path]) -> list[dict[str, Any]]:
    """:func:`replay_peak_rss` of each bag with the defaults (every estimator, plots)."""
    return [replay_peak_rss(bag) for bag in bags]


__all__ = ["memory_against_length", "replay_peak_rss"]
