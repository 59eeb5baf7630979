"""Execution of a list of cases on Dask, a process pool or serially."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from tire_estimation.evaluation.campaign.run import run_case
from tire_estimation.evaluation.campaign.spec import CampaignError, CaseSpec


def execute_cases(
    cases: Sequence[CaseSpec],
    executor: str = "dask",
    n_workers: int = 2,
    scheduler: str | None = None,
    threads: bool = False,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
    accuracy_at_s: float = 600.0,
) -> list[dict[str, Any]]:
    """Run every case; rows in the order of ``cases``.

    ``executor``: ``dask`` (``scheduler`` address, else a LocalCluster of ``n_workers``
    single-threaded worker processes, or threads only with ``threads=True``), ``processes``
    (``concurrent.futures.ProcessPoolExecutor``) or ``serial``.
    """
    if n_workers < 1:
        raise CampaignError(f"n_workers={n_workers!r}: must be >= 1")
    rows: dict[str, dict[str, Any]] = {}
    total = len(cases)

    def done(row: dict[str, Any]) -> None:
        rows[row["case_id"]] = row
        if progress is not None:
            progress(row, len(rows), total)

    if executor == "serial":
        for spec in cases:
            done(run_case(spec, accuracy_at_s))
    elif executor == "processes":
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(max_workers=n_workers) as pool:
            futures = [pool.submit(run_case, spec, accuracy_at_s) for spec in cases]
            for fut in as_completed(futures):
                done(fut.result())
    elif executor == "dask":
        try:
            from dask.distributed import Client, LocalCluster, as_completed
        except ImportError as exc:  # pragma: no cover - dask is a pinned dependency
            raise CampaignError(
                "dask.distributed is not installed; use --executor processes"
            ) from exc
        cluster = None
        if scheduler:
            client = Client(scheduler)
        else:
            cluster = LocalCluster(
                n_workers=n_workers,
                threads_per_worker=1,
                processes=not threads,
                dashboard_address=":0",
            )
            client = Client(cluster)
        try:
            futures = client.map(run_case, list(cases), accuracy_at_s=accuracy_at_s, pure=False)
            for fut in as_completed(futures):
                done(fut.result())
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    else:
        raise CampaignError(f"executor={executor!r}: must be dask, processes or serial")
    return [rows[spec.case_id] for spec in cases]
