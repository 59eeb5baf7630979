"""One wheel-speed signal copied to both rear wheels on a low-speed city drive.

Simulates ``city`` (seed 0, 5 min), replaces the rear-right wheel speed by the rear-left one (a
wiring fault, or a vehicle that reports one rear speed twice) and runs the radius MPF with its
defaults (on an axle whose wheels turn alike it takes the heading change from the gyro). Prints
the rear estimates and the error of their mean against the rear-left tyre's true radius (with
the copied signal both rear estimates should be the rear-left radius), the rear axle's verdict,
and the same for the unmodified drive.

    python scripts/copied_rear_signal.py
"""

from __future__ import annotations

import dataclasses

from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.evaluation.runner import RadiusRecorder
from tire_estimation.sim import simulate
from tire_estimation.sources import sim_samples


def main() -> None:
    sim = simulate("city", seed=0, minutes=5)
    true_mm = (sim.truth.wheel_radius_m[-1, 2:] - sim.vehicle.nominal_tire_radius_m) * 1e3
    print(f"truth rl / rr: {true_mm[0]:+.3f} / {true_mm[1]:+.3f} mm")
    ws = sim.wheel_speeds
    copied = ws.wheel_speed_rad_s.copy()
    copied[:, 3] = copied[:, 2]
    sim_copied = dataclasses.replace(
        sim, wheel_speeds=dataclasses.replace(ws, wheel_speed_rad_s=copied)
    )
    for name, drive, ref_mm in (
        ("unmodified", sim, float(true_mm.mean())),
        ("copied", sim_copied, float(true_mm[0])),
    ):
        recorder = RadiusRecorder()
        pipeline = EstimationPipeline(
            PipelineConfig(radius=RadiusEstimatorConfig()), sim.vehicle, observers=[recorder]
        )
        pipeline.push_ordered(sim_samples(drive, tire_forces=False))
        trace = recorder.finish(pipeline).arrays()
        est_mm = trace["radius_error_m"][-1] * 1e3
        assert pipeline.axles is not None
        print(
            f"{name:10s} rear {est_mm[0]:+.3f} / {est_mm[1]:+.3f} mm, common error "
            f"{est_mm.mean() - ref_mm:+.3f} mm; rear axle: {pipeline.axles.status('rear').reason}"
        )


if __name__ == "__main__":
    main()
