"""The replay is explicit state only: it never reads or writes a node's persistence file."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest


def test_the_replay_does_not_import_the_persistence_module() -> None:
    code = (
        "import sys, tire_estimation.replay, tire_estimation.cli, "
        "tire_estimation.evaluation.runner; "
        "print('tire_estimation.persistence' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "False"


def test_a_replay_leaves_the_node_files_untouched(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With a node's saved radii for the bag's vehicle in the default place, a replay neither
    reads them (every persistence function fails if called) nor writes anything there."""
    import numpy as np

    import tire_estimation.persistence as persistence
    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.radius.estimator import RadiusEstimator
    from tire_estimation.replay import run_replay
    from tire_estimation.sim import simulate

    sim = simulate("lane_change", seed=1, minutes=0.5)
    bag = write_sim_bag(sim, tmp_path / "bag")
    home = tmp_path / "home"
    monkeypatch.setenv("HOME", str(home))
    state_dir = home / ".ros" / "tire_estimation"
    est = RadiusEstimator(
        RadiusEstimatorConfig(n_particles=50), sim.vehicle, np.random.default_rng()
    )
    identity = persistence.Identity(sim.vehicle.name, "default")
    persistence.save_state(
        state_dir / "learned_radii.json", identity, {"radius": est.state_dict()}
    )
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in home.rglob("*") if p.is_file()}

    def forbidden(*args: object, **kwargs: object) -> None:
        raise AssertionError("the replay used the node's persistence")

    for name in ("read_json", "load_state", "restore", "save_state", "delete_state"):
        monkeypatch.setattr(persistence, name, forbidden)
    cfg = RadiusEstimatorConfig(n_particles=100)
    run_replay(bag, tmp_path / "out", config=cfg, plots=False, progress=False, stiffness=False)
    after = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in home.rglob("*") if p.is_file()}
    assert after == before and len(before) == 1
