"""``tire-estimation replay BAG1 BAG2 ...`` or ``replay DIR``: the replay over a fleet's bags.

Each bag is replayed (:func:`~tire_estimation.replay.run_replay`) in a task on Dask, as the
campaigns run their cases: a :func:`~tire_estimation.evaluation.campaign.execute.local_cluster`
on 127.0.0.1 by default, a running scheduler with ``scheduler``. Each bag's report goes to its
own subdirectory of the output directory; ``fleet.csv`` and ``fleet.md`` pool them, a row per
bag grouped by vehicle in the order of the drives: the learned radii over time, the deflation
alarms, whether the innovations were consistent. A bag that fails has its error in its row and
does not stop the others.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tire_estimation.atomic_io import atomic_write_text
from tire_estimation.errors import BagError, ConfigError, one_line
from tire_estimation.paths import prepare_out_dir

#: what a fleet run writes in its output directory (besides a directory per bag)
FLEET_FILES = ("fleet.csv", "fleet.md")
#: longest error text in a row
MAX_ERROR = 300


def is_bag(path: Path) -> bool:
    """A rosbag2 bag: a directory with ``metadata.yaml``, or a single ``.mcap``/``.db3`` file."""
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix in (".mcap", ".db3")


def bags_under(directory: Path) -> list[Path]:
    """The bags in ``directory`` and below (bag directories; a bag's own files are not
    searched), sorted by path."""
    found = sorted(meta.parent for meta in directory.rglob("metadata.yaml"))
    bags: list[Path] = []
    for path in found:
        if not any(path.is_relative_to(b) for b in bags):
            bags.append(path)
    return bags


def is_fleet(paths: Sequence[Path]) -> bool:
    """Whether ``replay PATHS`` replays a fleet: more than one path, or a directory that is not
    a bag but holds bags (anything else is one bag, with the single-bag report and errors)."""
    if len(paths) != 1:
        return True
    path = paths[0]
    return path.is_dir() and not is_bag(path) and bool(bags_under(path))


def find_bags(paths: Sequence[Path]) -> list[Path]:
    """Each path that is a bag (or not a directory: its replay reports why it is no bag), and
    the bags under each directory that is not one.

    Raises:
        BagError: a directory holds no bag.
    """
    bags: list[Path] = []
    for path in paths:
        if not path.is_dir() or is_bag(path):
            bags.append(path)
            continue
        under = bags_under(path)
        if not under:
            raise BagError(f"no rosbag2 bag (metadata.yaml) in or under {path}")
        bags.extend(under)
    return bags


def report_names(bags: Sequence[Path]) -> list[str]:
    """A subdirectory name per bag: its name (a file bag's without suffix), numbered when two
    bags share one."""
    names = [b.stem if b.is_file() else b.name or "bag" for b in bags]
    seen: dict[str, int] = {}
    out = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        out.append(name if names.count(name) == 1 else f"{name}_{seen[name]}")
    return out


def replay_one(bag: str, out: str, options: dict[str, Any]) -> dict[str, Any]:
    """Replay one bag into ``out`` (a Dask task): its row of the pooled table. Errors are
    caught and given in the row."""
    from tire_estimation.bag.reader import open_bag
    from tire_estimation.replay import run_replay

    start = time.perf_counter()
    row: dict[str, Any] = {"bag": bag, "report": out, "status": "ok", "error": ""}
    try:
        report = run_replay(bag, out, progress=False, **options)
        meta, _, _ = open_bag(bag, topics=[])
        row.update(vehicle=meta.vehicle.name, start_ns=meta.start_ns, **_figures(report.metrics))
    except Exception as exc:  # every failure of one bag is its row's error
        row.update(status="failed", error=one_line(f"{type(exc).__name__}: {exc}", MAX_ERROR))
    row["wall_s"] = round(time.perf_counter() - start, 2)
    return row


def _figures(m: dict[str, Any]) -> dict[str, Any]:
    """The pooled columns of one report: final radius error and std per wheel (mm), the
    deflation alarms, the consistency verdict, the position RMSE."""
    radii = m["radii"]
    out: dict[str, Any] = {"duration_s": round(float(m["duration_s"]), 1)}
    for wheel, err in radii["final_radius_error_m"].items():
        std = radii["final_radius_error_std_m"].get(wheel)
        out[f"{wheel}_mm"] = None if err is None else round(1e3 * err, 3)
        out[f"{wheel}_std_mm"] = None if std is None else round(1e3 * std, 3)
    det = m.get("detection") or {}
    alarms = [f"{a['wheel']}@{a['t_s']:.0f}s" for a in det.get("alarms", [])]
    out["alarms"] = " ".join(alarms) if alarms else ("none" if det.get("armed") else "not armed")
    out["consistent"] = m["residuals"].get("consistent")
    rmse = m["position"]["rmse_m"]
    out["position_rmse_m"] = None if rmse is None else round(rmse, 2)
    return out


@dataclass
class FleetResult:
    """Rows of the pooled table (in the order of the bags) and the files written."""

    rows: list[dict[str, Any]]
    files: list[Path] = field(default_factory=list)

    @property
    def failed(self) -> list[dict[str, Any]]:
        """The rows of the bags that failed."""
        return [r for r in self.rows if r["status"] != "ok"]


def run_fleet(
    paths: Sequence[Path],
    out_dir: Path,
    options: dict[str, Any],
    *,
    scheduler: str | None = None,
    n_workers: int | None = None,
    threads: bool = False,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
) -> FleetResult:
    """Replay every bag of ``paths`` (:func:`find_bags`) on Dask into a subdirectory of
    ``out_dir`` each, then write ``fleet.csv`` and ``fleet.md``.

    ``options``: keyword arguments of :func:`~tire_estimation.replay.run_replay` (``config_path``,
    ``plots``, ``stiffness``, ``rank_effects``, ``rank_seeds``). ``scheduler``: address of a
    running Dask scheduler; else a local cluster of ``n_workers`` (default: one per bag, at
    most the number of CPUs) single-threaded worker processes (threads with ``threads``).
    ``progress(row, done, total)`` is called as each bag finishes.
    """
    import os

    from dask.distributed import Client, as_completed

    from tire_estimation.evaluation.campaign.execute import local_cluster

    if options.get("write_config") is not None:
        raise ConfigError("--write-config", str(options["write_config"]), "needs a single bag")
    bags = find_bags(paths)
    out = prepare_out_dir(Path(out_dir))
    outs = [str(out / name) for name in report_names(bags)]
    workers = n_workers or max(1, min(len(bags), os.cpu_count() or 1))
    cluster = None if scheduler else local_cluster(workers, threads=threads)
    client = Client(scheduler if scheduler else cluster)
    rows: dict[str, dict[str, Any]] = {}
    try:
        futures = client.map(replay_one, [str(b) for b in bags], outs, options=options, pure=False)
        where = {fut.key: (str(b), o) for fut, b, o in zip(futures, bags, outs, strict=True)}
        for fut in as_completed(futures):
            bag, report = where[fut.key]
            try:
                row = fut.result()
            except Exception as exc:  # the task itself failed (a worker lost, ...)
                error = one_line(f"{type(exc).__name__}: {exc}", MAX_ERROR)
                row = {"bag": bag, "report": report, "status": "failed", "error": error}
            rows[bag] = row
            if progress is not None:
                progress(row, len(rows), len(bags))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    ordered = [rows[str(b)] for b in bags]
    result = FleetResult(ordered)
    result.files = write_tables(out, ordered)
    return result


def _by_vehicle(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows grouped by vehicle (name order), each vehicle's drives in time order; failed bags
    last."""
    ok = [r for r in rows if r["status"] == "ok"]
    ok.sort(key=lambda r: (str(r.get("vehicle")), r.get("start_ns") or 0, r["bag"]))
    return ok + [r for r in rows if r["status"] != "ok"]


def write_tables(out: Path, rows: Sequence[dict[str, Any]]) -> list[Path]:
    """``fleet.csv`` (a row per bag, columns the union of the rows') and ``fleet.md`` (a
    table per vehicle, then the failed bags) in ``out``."""
    from tire_estimation.evaluation.campaign.output import write_csv

    ordered = _by_vehicle(rows)
    csv_path, md_path = out / FLEET_FILES[0], out / FLEET_FILES[1]
    write_csv(csv_path, ordered)
    atomic_write_text(md_path, markdown(ordered))
    return [csv_path, md_path]


def markdown(rows: Sequence[dict[str, Any]]) -> str:
    """The pooled table as markdown: per vehicle its drives in time order (final radius errors
    ± std in mm, alarms, consistency, position RMSE), then the bags that failed."""
    ok = [r for r in rows if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] != "ok"]
    lines = [f"# Fleet replay: {len(rows)} bags, {len(failed)} failed", ""]
    for vehicle in dict.fromkeys(str(r.get("vehicle")) for r in ok):
        drives = [r for r in ok if str(r.get("vehicle")) == vehicle]
        wheels = list(dict.fromkeys(k[:-3] for r in drives for k in r if k.endswith("_mm")))
        wheels = [w for w in wheels if not w.endswith("_std")]
        lines += [f"## {vehicle}", ""]
        head = ["bag", "duration s", *(f"{w} mm" for w in wheels)]
        head += ["alarms", "consistent", "position RMSE m"]
        lines.append("| " + " | ".join(head) + " |")
        lines.append("|" + "---|" * len(head))
        for r in drives:
            cells = [Path(r["bag"]).name, _cell(r.get("duration_s"))]
            for w in wheels:
                err, std = r.get(f"{w}_mm"), r.get(f"{w}_std_mm")
                cells.append("-" if err is None else f"{err:+.3f} ± {std:.3f}")
            cells += [str(r.get("alarms")), _cell(r.get("consistent"))]
            cells.append(_cell(r.get("position_rmse_m")))
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    if failed:
        lines += ["## Failed", "", "| bag | error |", "|---|---|"]
        for r in failed:
            lines.append(f"| {r['bag']} | {r['error'].replace('|', '/')} |")
        lines.append("")
    return "\n".join(lines)


def _cell(value: Any) -> str:
    return "-" if value is None else str(value)
