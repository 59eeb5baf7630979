"""Execution of case lists (evaluation.campaign.execute)."""

from __future__ import annotations

from urllib.parse import urlparse

import pytest

from tire_estimation.evaluation.campaign.execute import Execution, execute_cases, local_cluster
from tire_estimation.evaluation.campaign.spec import (
    CampaignError,
    CaseSpec,
)


def test_unknown_executor_and_bad_worker_count_are_campaign_errors() -> None:
    with pytest.raises(CampaignError, match="carrier-pigeon"):
        Execution(executor="carrier-pigeon")
    with pytest.raises(CampaignError, match="n_workers"):
        Execution(executor="serial", n_workers=0)


@pytest.mark.parametrize("executor", ["serial", "processes"])
def test_executors_keep_case_order(executor: str) -> None:
    specs = [
        CaseSpec(case_id=f"bad-{i}", kind="step", scenario="nope", seed=i, minutes=1.0)
        for i in range(3)
    ]
    rows = execute_cases(specs, Execution(executor=executor, n_workers=2))
    assert [r["case_id"] for r in rows] == ["bad-0", "bad-1", "bad-2"]
    assert all("ScenarioError" in r["error"] for r in rows)


@pytest.mark.parametrize("threads", [True, False])
def test_the_local_cluster_listens_on_localhost_only(threads: bool) -> None:
    """Scheduler, workers and dashboards of the campaign's LocalCluster: 127.0.0.1 only (Dask
    exchanges pickled data; the dashboard has no authentication)."""
    psutil = pytest.importorskip("psutil")
    with local_cluster(1, threads=threads) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        assert urlparse(cluster.dashboard_link).hostname == "127.0.0.1"
        workers = list(cluster.scheduler_info["workers"])
        assert len(workers) == 1 and workers[0].startswith("tcp://127.0.0.1:")
        me = psutil.Process()
        listening = [
            conn.laddr.ip
            for proc in (me, *me.children(recursive=True))
            for conn in proc.net_connections(kind="inet")
            if conn.status == psutil.CONN_LISTEN
        ]
        # scheduler, its dashboard, the worker and its dashboard (and nanny, for processes)
        assert len(listening) >= 4
        assert set(listening) == {"127.0.0.1"}
