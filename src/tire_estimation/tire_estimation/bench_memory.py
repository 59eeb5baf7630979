"""Peak memory of the replay against drive length (part of ``make bench``).

Each bag is replayed by ``tire-estimation replay BAG --out DIR --no-progress`` in a process of
its own, which reports its peak resident set size at the end (``VmHWM`` of
``/proc/self/status``: the high-water mark of the process's own memory since it started the
interpreter; ``ru_maxrss`` would include the pages of the parent it was forked from): the
interpreter, imports, the run and the report.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

#: run in the child: the replay command line, then the process's own peak RSS on stdout (kB)
_CHILD = (
    "import sys\n"
    "from tire_estimation.cli import main\n"
    "code = main(sys.argv[1:])\n"
    "with open('/proc/self/status') as f:\n"
    "    hwm = [line.split()[1] for line in f if line.startswith('VmHWM:')]\n"
    "print('VmHWM_kB', hwm[0] if hwm else 0)\n"
    "sys.exit(code)\n"
)


def replay_peak_rss(bag: Path, *, stiffness: bool = True, plots: bool = True) -> dict[str, Any]:
    """Replay ``bag`` in a child process; its peak RSS (MB), wall time and drive duration."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [
            sys.executable, "-c", _CHILD, "replay", str(bag), "--out", out, "--no-progress",
        ]  # fmt: skip
        if not stiffness:
            cmd.append("--no-stiffness")
        if not plots:
            cmd.append("--no-plots")
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        wall_s = time.perf_counter() - t0
        if proc.returncode != 0:
            text = proc.stderr.strip().splitlines()
            raise RuntimeError(f"replay of {bag} failed: {text[-1] if text else proc.returncode}")
        hwm_kb = [
            int(line.split()[1])
            for line in proc.stdout.splitlines()
            if line.startswith("VmHWM_kB")
        ]
        metrics = json.loads((Path(out) / "metrics.json").read_text())
    return {
        "bag": str(bag),
        "duration_s": float(metrics["duration_s"]),
        "wall_s": wall_s,
        "peak_rss_mb": (hwm_kb[-1] if hwm_kb else 0) * 1024 / 1e6,
        "stiffness": stiffness,
        "plots": plots,
    }


def memory_against_length(bags: list[Path]) -> list[dict[str, Any]]:
    """:func:`replay_peak_rss` of each bag with the defaults (every estimator, plots)."""
    return [replay_peak_rss(bag) for bag in bags]


__all__ = ["memory_against_length", "replay_peak_rss"]
