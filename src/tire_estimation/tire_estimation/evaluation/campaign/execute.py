"""Execution of a list of cases on Dask, a process pool or serially.

The Dask LocalCluster listens on 127.0.0.1 only (scheduler, workers, dashboards): Dask sends
pickled data and the dashboard has no authentication, so nothing is reachable from the network
unless ``dashboard_address`` asks for it. A remote scheduler is the user's choice
(``docs/campaign.md``: TLS, and connect only to schedulers you trust).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from tire_estimation.evaluation.campaign.run import run_case
from tire_estimation.evaluation.campaign.spec import CampaignError, CaseSpec

if TYPE_CHECKING:
    from dask.distributed import LocalCluster

#: interface the LocalCluster's scheduler, workers and dashboards listen on
LOCAL_HOST = "127.0.0.1"
#: default dashboard address of the LocalCluster: this machine only, a free port
DEFAULT_DASHBOARD_ADDRESS = f"{LOCAL_HOST}:0"
#: the ways to run the cases
EXECUTORS = ("dask", "processes", "serial")


@dataclass(frozen=True)
class Execution:
    """Where the cases of a study run (checked at construction).

    ``executor``: ``dask`` (``scheduler`` address, else :func:`local_cluster` of ``n_workers``
    single-threaded worker processes, or threads only with ``threads=True``, its dashboard on
    ``dashboard_address``), ``processes`` (``concurrent.futures.ProcessPoolExecutor`` of
    ``n_workers``) or ``serial``.
    """

    executor: str = "dask"
    n_workers: int = 2
    scheduler: str | None = None
    threads: bool = False
    dashboard_address: str | None = None

    def __post_init__(self) -> None:
        if self.n_workers < 1:
            raise CampaignError(f"n_workers={self.n_workers!r}: must be >= 1")
        if self.executor not in EXECUTORS:
            raise CampaignError(f"executor={self.executor!r}: must be dask, processes or serial")


def local_cluster(
    n_workers: int, threads: bool = False, dashboard_address: str | None = None
) -> LocalCluster:
    """A Dask LocalCluster of ``n_workers`` single-threaded workers (processes, or threads with
    ``threads=True``) whose scheduler, workers and dashboards listen on 127.0.0.1 only; the
    scheduler's dashboard on ``dashboard_address`` (default 127.0.0.1, a free port; e.g.
    ``:8787`` for every interface, when asked)."""
    from dask.distributed import LocalCluster

    return LocalCluster(
        n_workers=n_workers,
        threads_per_worker=1,
        processes=not threads,
        # TCP on the loopback interface for threads too (their in-process transport would
        # still open each worker's dashboard on every interface)
        protocol="tcp://",
        host=LOCAL_HOST,
        dashboard_address=dashboard_address or DEFAULT_DASHBOARD_ADDRESS,
        worker_dashboard_address=f"{LOCAL_HOST}:0",
    )


def execute_cases(
    cases: Sequence[CaseSpec],
    execution: Execution | None = None,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
    accuracy_at_s: float = 600.0,
) -> list[dict[str, Any]]:
    """Run every case as ``execution`` says (default :class:`Execution`); rows in the order of
    ``cases``."""
    ex = execution or Execution()
    rows: dict[str, dict[str, Any]] = {}
    total = len(cases)

    def done(row: dict[str, Any]) -> None:
        rows[row["case_id"]] = row
        if progress is not None:
            progress(row, len(rows), total)

    if ex.executor == "serial":
        for spec in cases:
            done(run_case(spec, accuracy_at_s))
    elif ex.executor == "processes":
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(max_workers=ex.n_workers) as pool:
            futures = [pool.submit(run_case, spec, accuracy_at_s) for spec in cases]
            for fut in as_completed(futures):
                done(fut.result())
    else:
        try:
            from dask.distributed import Client, as_completed
        except ImportError as exc:  # pragma: no cover - dask is a pinned dependency
            raise CampaignError(
                "dask.distributed is not installed; use --executor processes"
            ) from exc
        cluster = None
        if ex.scheduler:
            client = Client(ex.scheduler)
        else:
            cluster = local_cluster(ex.n_workers, ex.threads, ex.dashboard_address)
            client = Client(cluster)
        try:
            futures = client.map(run_case, list(cases), accuracy_at_s=accuracy_at_s, pure=False)
            for fut in as_completed(futures):
                done(fut.result())
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    return [rows[spec.case_id] for spec in cases]
