"""A human-readable summary of a contract bag (``tire-estimation info``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tire_estimation.bag.reader import read_bag


def describe_bag(path: str | Path) -> str:
    """Topics with counts and rates, duration, vehicle, scenario and events of a bag."""
    data = read_bag(path)
    lines = [f"bag:       {data.path}", f"duration:  {data.duration_s:.1f} s"]
    if data.scenario:
        lines.append(f"scenario:  {data.scenario} (seed {data.seed})")
    v = data.vehicle
    lines.append(
        f"vehicle:   {v.name}: nominal radius {v.nominal_tire_radius_m:.4f} m, track "
        f"{v.track_width_m:.3f} m, wheelbase {v.wheelbase_m:.3f} m, mass {v.mass_kg:.0f} kg, "
        f"{v.drive}-wheel drive"
    )
    lines.append("topics:")
    width = max((len(t) for t in data.topics), default=10)
    for topic, info in sorted(data.topics.items()):
        rate = info.count / data.duration_s if data.duration_s > 0 else 0.0
        lines.append(f"  {topic:<{width}}  {info.count:>8d} msgs  {rate:7.1f} Hz  {info.msgtype}")
    if data.truth_wheel_radii is not None and data.truth_wheel_radii.values.size:
        radii = data.truth_wheel_radii
        first = ", ".join(
            f"{n} {1e3 * r:.2f}" for n, r in zip(radii.names, radii.values[0], strict=True)
        )
        last = ", ".join(
            f"{n} {1e3 * r:.2f}" for n, r in zip(radii.names, radii.values[-1], strict=True)
        )
        lines.append(f"true radii at start (mm): {first}")
        lines.append(f"true radii at end   (mm): {last}")
    if data.wheel_speeds is not None and data.wheel_speeds.t_ns.size:
        speed = np.nanmean(data.wheel_speeds.wheel_speed_rad_s[:, 2:], axis=1)
        speed_kmh = 3.6 * speed * v.nominal_tire_radius_m
        lines.append(
            f"speed (rear wheels, km/h): mean {np.mean(speed_kmh):.1f}, "
            f"min {np.min(speed_kmh):.1f}, max {np.max(speed_kmh):.1f}"
        )
    for event in data.events:
        detail = ", ".join(f"{k}={val}" for k, val in event.detail.items())
        lines.append(f"event:     t={event.t_s:.1f} s {event.kind} {detail}")
    for note in data.notes:
        lines.append(f"note:      {note}")
    return "\n".join(lines)
