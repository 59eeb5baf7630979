"""Benchmarks (``make bench``): filter step time (radius MPF, stiffness MPF, and the two side by
side per sample), replay real-time factor (radius only, and the default replay with every
estimator), the IMU-driven estimators' cost per IMU sample on the replay's samples, the replay's
peak memory against drive length (:mod:`.bench_memory`), node latency over DDS and the node's own
callback time (in-process, no DDS).

Not part of the tests: numbers depend on the machine and its load. Results are printed as JSON
(and written to ``--out`` if given); docs/results.md quotes them with the command.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.bench_memory import memory_against_length
from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.estimator import RadiusEstimator
from tire_estimation.core.vehicle import VehicleParams

ROOT = Path(__file__).resolve().parents[3]
DEMO_BAG = ROOT / "bags" / "ece_r64_6min"


def step_time_us(n_particles: int, seconds: float = 60.0, seed: int = 0) -> dict[str, float]:
    """Mean wall time per 100 Hz wheel-speed step (GNSS at 10 Hz included), in µs."""
    vehicle = VehicleParams()
    cfg = RadiusEstimatorConfig(n_particles=n_particles, seed=seed)
    est = RadiusEstimator(cfg, vehicle, np.random.default_rng(seed))
    ltp = LocalTangentPlane(58.4, 15.6, 100.0)
    rng = np.random.default_rng(seed + 1)
    speed, radius = 25.0, vehicle.nominal_tire_radius_m
    n = int(seconds * 100)
    curvature = 0.002 * np.sin(np.arange(n) * 0.01 * 2 * np.pi / 60.0)
    yaw = np.cumsum(speed * curvature * 0.01)
    east = np.cumsum(speed * np.cos(yaw) * 0.01)
    north = np.cumsum(speed * np.sin(yaw) * 0.01)
    half = 0.5 * vehicle.track_width_m
    omega_l = (speed - speed * curvature * half) / radius
    omega_r = (speed + speed * curvature * half) / radius
    lat, lon, alt = ltp.to_lla(
        east + rng.normal(0, 1.5, n), north + rng.normal(0, 1.5, n), 0 * east
    )
    cov = np.diag([2.25, 2.25, 4.0])
    t0 = 1_700_000_000_000_000_000
    wheels = np.column_stack([omega_l, omega_r, omega_l, omega_r])
    warm = n // 4
    times = []
    for k in range(n):
        t = t0 + k * 10_000_000
        start = time.perf_counter()
        est.on_wheel_speeds(t, wheels[k])
        if k % 10 == 0:
            est.on_gnss_fix(t, float(lat[k]), float(lon[k]), float(alt[k]), cov)
        if k >= warm:
            times.append(time.perf_counter() - start)
    arr = np.asarray(times) * 1e6
    return {"mean_us": float(arr.mean()), "median_us": float(np.median(arr)),
            "p99_us": float(np.quantile(arr, 0.99))}  # fmt: skip


def stiffness_step_time_ms(
    n_particles: int, seconds: float = 10.0, seed: int = 0
) -> dict[str, float]:
    """Wall time per IMU step of the stiffness MPF (issue 5: under 1 ms at N = 500), in ms.

    A simulated ``asphalt_sine`` drive is fed through :class:`StiffnessEstimator`; the steps of
    the ``seconds`` after its sine steering starts (at about 20 s; learning active) are timed:
    the whole ``on_imu`` and, ``mpf_*``, the filter's share (its predict and update, without the
    front-end's input checks and activation). On a shared machine the median is the cost of a
    step that no other job interrupted.
    """
    from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
    from tire_estimation.core.stiffness.estimator import StiffnessEstimator
    from tire_estimation.sim import simulate

    settle_s = 22.0
    sim = simulate("asphalt_sine", seed=seed, minutes=(settle_s + seconds) / 60.0)
    est = StiffnessEstimator(
        StiffnessEstimatorConfig(n_particles=n_particles), sim.vehicle, np.random.default_rng(seed)
    )
    filt = est.filter
    mpf_ns = [0]

    def timed(fn: Any) -> Any:
        def call(*args: Any) -> None:
            t0 = time.perf_counter_ns()
            fn(*args)
            mpf_ns[0] += time.perf_counter_ns() - t0

        return call

    filt.predict, filt.update = timed(filt.predict), timed(filt.update)  # type: ignore[method-assign]
    ws, st, imu = sim.wheel_speeds, sim.steering, sim.imu
    iw = np.searchsorted(ws.t_ns, imu.t_ns, side="right") - 1
    ist = np.searchsorted(st.t_ns, imu.t_ns, side="right") - 1
    times, mpf_times, active = [], [], 0
    warm = int(np.searchsorted(imu.t_ns, imu.t_ns[0] + round(settle_s * 1e9)))
    for k in range(imu.t_ns.size):
        t = int(imu.t_ns[k])
        if iw[k] >= 0:
            est.on_wheel_speeds(int(ws.t_ns[iw[k]]), ws.wheel_speed_rad_s[iw[k]])
        if ist[k] >= 0:
            est.on_steering(int(st.t_ns[ist[k]]), float(st.angle_rad[ist[k]]))
        mpf_ns[0] = 0
        start = time.perf_counter_ns()
        est.on_imu(t, imu.angular_velocity_rad_s[k], imu.linear_acceleration_m_s2[k])
        if k >= warm:
            times.append(time.perf_counter_ns() - start)
            mpf_times.append(mpf_ns[0])
            active += int(est.estimate().active)
    arr = np.asarray(times) * 1e-6
    mpf = np.asarray(mpf_times) * 1e-6
    return {"mean_ms": float(arr.mean()), "median_ms": float(np.median(arr)),
            "p99_ms": float(np.quantile(arr, 0.99)), "mpf_mean_ms": float(mpf.mean()),
            "mpf_median_ms": float(np.median(mpf)),
            "learning_fraction": active / max(len(times), 1)}  # fmt: skip


def per_sample_costs(particles: list[int]) -> dict[str, dict[str, float]]:
    """Per-sample cost side by side, µs, one run: the radius MPF per wheel-speed sample
    (:func:`step_time_us`, GNSS included) and the stiffness MPF per IMU sample
    (:func:`stiffness_step_time_ms`: the whole ``on_imu`` and the filter alone), at each N."""
    out: dict[str, dict[str, float]] = {}
    for n in particles:
        radius = step_time_us(n)
        stiff = stiffness_step_time_ms(n)
        out[str(n)] = {
            "radius_mean_us": radius["mean_us"], "radius_median_us": radius["median_us"],
            "stiffness_on_imu_mean_us": 1e3 * stiff["mean_ms"],
            "stiffness_on_imu_median_us": 1e3 * stiff["median_ms"],
            "stiffness_mpf_mean_us": 1e3 * stiff["mpf_mean_ms"],
            "stiffness_mpf_median_us": 1e3 * stiff["mpf_median_ms"],
        }  # fmt: skip
    return out


def imu_estimator_costs(bag: Path) -> dict[str, Any]:
    """CPU time per IMU sample, µs, of each IMU-driven lateral estimator of the default replay
    (the stiffness MPF, defaults, and its linear-KF baseline) on ``bag``'s samples, fed as the
    replay's pipeline feeds them (wheel speeds, steering, measured speed, IMU) with one
    ``estimate()`` after each IMU sample, as the replay's lateral recorder takes it at 100 Hz;
    and the share of IMU samples at which the stiffness MPF learns."""
    from tire_estimation.bag.reader import read_bag
    from tire_estimation.core.lateral.linear_kf import LinearLateralKF, LinearLateralKFConfig
    from tire_estimation.core.samples import ImuSample, MeasuredVelocity, Steering, WheelSpeeds
    from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
    from tire_estimation.core.stiffness.estimator import StiffnessEstimator
    from tire_estimation.sources import bag_samples

    data = read_bag(bag)
    kinds = (ImuSample, WheelSpeeds, Steering, MeasuredVelocity)
    samples = [s for s in bag_samples(data) if type(s) in kinds]
    n_imu = sum(type(s) is ImuSample for s in samples)
    learning = 0

    def feed(est: Any) -> float:
        nonlocal learning
        learning = 0
        start = time.process_time()
        for s in samples:
            if type(s) is ImuSample:
                est.on_imu(s.t_ns, s.angular_velocity_rad_s, s.linear_acceleration_m_s2)
                learning += bool(getattr(est.estimate(), "active", False))
            elif type(s) is WheelSpeeds:
                est.on_wheel_speeds(s.t_ns, s.wheel_speed_rad_s)
            elif type(s) is Steering:
                est.on_steering(s.t_ns, s.angle_rad)
            else:
                est.on_velocity(s.t_ns, s.vx_m_s)
        return 1e6 * (time.process_time() - start) / max(n_imu, 1)

    linear_us = feed(LinearLateralKF(LinearLateralKFConfig(), data.vehicle))
    rng = np.random.default_rng([0, 1])
    stiffness_us = feed(StiffnessEstimator(StiffnessEstimatorConfig(), data.vehicle, rng))
    return {"imu_samples": n_imu, "stiffness_mpf_us": stiffness_us, "linear_kf_us": linear_us,
            "stiffness_learning_fraction": learning / max(n_imu, 1)}  # fmt: skip


def tyre_force_costs(bag: Path) -> dict[str, Any]:
    """CPU time per tyre-force sample, µs, of the tyre-force KF (defaults) on ``bag``'s
    samples, fed as the replay's pipeline feeds it (wheel speeds, steering, tyre forces) with
    its estimate after each step, as the pipeline returns it; empty without tyre forces."""
    from tire_estimation.bag.reader import read_bag
    from tire_estimation.core.lateral.tyre_force_kf import TyreForceEstimator, TyreForceKFConfig
    from tire_estimation.core.samples import Steering, TireForces, WheelSpeeds
    from tire_estimation.sources import bag_samples

    data = read_bag(bag)
    samples = [s for s in bag_samples(data) if type(s) in (TireForces, WheelSpeeds, Steering)]
    n = sum(type(s) is TireForces for s in samples)
    if n == 0:
        return {}
    est = TyreForceEstimator(TyreForceKFConfig(), data.vehicle)
    # the first steps load the compiled kernels: one pass before the timed one
    for _pass in range(2):
        est.reset()
        start = time.process_time()
        for s in samples:
            if type(s) is TireForces:
                est.on_tire_forces(s.t_ns, s.fx_n, s.fy_n, s.fz_n, s.valid)
            elif type(s) is WheelSpeeds:
                est.on_wheel_speeds(s.t_ns, s.wheel_speed_rad_s)
            else:
                est.on_steering(s.t_ns, s.angle_rad)
        cpu_s = time.process_time() - start
    return {"tire_force_samples": n, "tyre_force_kf_us": 1e6 * cpu_s / n}


def replay_rtf(
    n_particles: int | None, bag: Path = DEMO_BAG, stiffness: bool = False
) -> dict[str, float]:
    """Replay ``bag`` (decoding included, no plots); real-time factor and split.

    ``n_particles`` None: the default configuration (radius MPF N = 500, stiffness MPF N = 200);
    ``stiffness``: with the stiffness MPF and its linear-KF baseline (the default replay runs
    every estimator)."""
    from tire_estimation.replay import run_replay

    cfg = None if n_particles is None else RadiusEstimatorConfig(n_particles=n_particles)
    with tempfile.TemporaryDirectory() as out:
        report = run_replay(bag, out, config=cfg, plots=False, progress=False, stiffness=stiffness)
    m = report.metrics
    return {"duration_s": m["duration_s"], "wall_s": m["wall_s"],
            "realtime_factor": m["realtime_factor"], "read_s": m["timing_s"]["read"],
            "estimate_s": m["timing_s"]["estimate"]}  # fmt: skip


def node_latency(seconds: float = 20.0, n_particles: int = 500) -> dict[str, Any]:
    """estimator_node end-to-end latency: wheel-speed stamp (wall clock) to odometry arrival.

    Wheel speeds at 100 Hz and GNSS fixes and Doppler velocities (used by default) at 10 Hz are
    published with header stamp = now; the node publishes odometry after every wheel-speed
    sample (``odometry_publish_period_s:=0``).
    """
    import rclpy
    from geometry_msgs.msg import TwistWithCovarianceStamped
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import JointState, NavSatFix

    exe = shutil.which("estimator_node")
    if exe is None:
        return {"error": "estimator_node not on PATH (source env.sh)"}
    proc = subprocess.Popen(
        [exe, "--ros-args", "-p", "persistence_file:=''", "-p", "odometry_publish_period_s:=0.0",
         "-p", f"radius.n_particles:={n_particles}", "--log-level", "warn"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=os.environ.copy(),
    )  # fmt: skip
    rclpy.init()
    node = rclpy.create_node("latency_bench")
    lat_ns: list[int] = []

    def on_odom(msg: Odometry) -> None:
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        lat_ns.append(time.time_ns() - stamp)

    node.create_subscription(Odometry, "/tire_estimation/odometry", on_odom, 100)
    pub_w = node.create_publisher(JointState, "/vehicle/wheel_speeds", qos_profile_sensor_data)
    pub_g = node.create_publisher(NavSatFix, "/gnss/fix", qos_profile_sensor_data)
    pub_v = node.create_publisher(
        TwistWithCovarianceStamped, "/gnss/velocity", qos_profile_sensor_data
    )
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        deadline = time.monotonic() + 30
        while node.count_subscribers("/vehicle/wheel_speeds") < 1 and time.monotonic() < deadline:
            time.sleep(0.1)
        ltp = LocalTangentPlane(58.4, 15.6, 100.0)
        speed, omega = 25.0, 25.0 / 0.31
        wheel = JointState(name=["wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"])
        fix = NavSatFix()
        fix.position_covariance = [2.25, 0, 0, 0, 2.25, 0, 0, 0, 4.0]
        fix.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        fix.status.status = 0
        vel = TwistWithCovarianceStamped()
        vel.header.frame_id = "map"
        vel.twist.twist.linear.x = speed
        vel.twist.covariance = [0.0025 if i in (0, 7) else 0.01 if i == 14 else 0.0
                                for i in range(36)]  # fmt: skip
        start = time.monotonic()
        k = 0
        while time.monotonic() - start < seconds:
            now = time.time_ns()
            wheel.header.stamp.sec, wheel.header.stamp.nanosec = divmod(now, 1_000_000_000)
            wheel.velocity = [omega] * 4
            pub_w.publish(wheel)
            if k % 10 == 0:
                la, lo, al = ltp.to_lla(speed * k * 0.01, 0.0, 0.0)
                fix.header.stamp = wheel.header.stamp
                fix.latitude, fix.longitude, fix.altitude = float(la), float(lo), float(al)
                pub_g.publish(fix)
                vel.header.stamp = wheel.header.stamp
                pub_v.publish(vel)
            k += 1
            time.sleep(max(0.0, start + k * 0.01 - time.monotonic()))
        time.sleep(1.0)
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=15)
        executor.shutdown()
        spinner.join(timeout=5)
        node.destroy_node()
        rclpy.shutdown()
    arr = np.asarray(lat_ns[len(lat_ns) // 10 :], dtype=float) * 1e-6  # skip start-up
    if arr.size == 0:
        return {"error": "no odometry received"}
    return {"inputs_sent": k, "outputs": len(lat_ns), "p50_ms": float(np.median(arr)),
            "p99_ms": float(np.quantile(arr, 0.99)), "max_ms": float(arr.max())}  # fmt: skip


def node_callback_time(
    seconds: float = 30.0, n_particles: int = 500, skip_s: float = 3.0, stiffness: bool = True
) -> dict[str, Any]:
    """The node's own share of the latency: wall time of ``estimator_node``'s subscription
    callbacks, called in-process (no DDS) with wheel speeds, steering and IMU at 100 Hz and GNSS
    fixes at 10 Hz, odometry published after every wheel-speed sample. A 25 m/s drive with a
    0.5 Hz, 2 deg sine steer (the stiffness MPF learns); ``stiffness`` False: the node without
    the stiffness MPF (``stiffness_enabled:=false``), the steering and IMU still delivered.
    ``skip_s`` of header time at the start are not counted. Percentiles of the wall time of
    single callbacks and of the callbacks of one 10 ms input period (``tick_*``), and of the
    CPU time of that thread per period (``tick_cpu_*``: what the callbacks cost without the
    time the process waited for a core on a shared machine)."""
    import math

    import rclpy
    from sensor_msgs.msg import Imu, JointState, NavSatFix

    from tire_estimation.nodes.estimator_node import EstimatorNode

    rclpy.init(args=["--ros-args", "-p", "persistence_file:=''", "-p",
                     "odometry_publish_period_s:=0.0", "-p",
                     f"radius.n_particles:={n_particles}", "-p",
                     f"stiffness_enabled:={str(stiffness).lower()}",
                     "--log-level", "warn"])  # fmt: skip
    try:
        node = EstimatorNode()
        callbacks = {sub.topic_name: sub.callback for sub in node.subscriptions}
        on_wheels, on_fix = callbacks["/vehicle/wheel_speeds"], callbacks["/gnss/fix"]
        on_steer, on_imu = callbacks["/vehicle/steering"], callbacks["/imu/data"]
        ltp = LocalTangentPlane(58.4, 15.6, 100.0)
        speed = 25.0
        wheelbase = node.vehicle.lf_m + node.vehicle.lr_m
        omega = speed / node.vehicle.nominal_tire_radius_m
        wheel = JointState(name=["wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"])
        steer = JointState(name=[node.names.steering])
        imu = Imu()
        fix = NavSatFix()
        fix.position_covariance = [2.25, 0, 0, 0, 2.25, 0, 0, 0, 4.0]
        fix.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        t0 = time.time_ns()
        wall: list[float] = []
        tick: list[float] = []
        tick_cpu: list[float] = []
        east = north = heading = 0.0
        for k in range(int(seconds * 100)):
            stamp = divmod(t0 + k * 10_000_000, 1_000_000_000)
            delta = math.radians(2.0) * math.sin(2.0 * math.pi * 0.5 * k * 0.01)
            yaw_rate = speed * delta / wheelbase
            heading += yaw_rate * 0.01
            east += speed * math.cos(heading) * 0.01
            north += speed * math.sin(heading) * 0.01
            steer.header.stamp.sec, steer.header.stamp.nanosec = stamp
            steer.position = [delta]
            imu.header.stamp = steer.header.stamp
            imu.angular_velocity.z = yaw_rate
            imu.linear_acceleration.y = speed * yaw_rate
            imu.linear_acceleration.z = 9.81
            wheel.header.stamp = steer.header.stamp
            wheel.velocity = [omega] * 4
            calls = [(on_steer, steer), (on_imu, imu), (on_wheels, wheel)]
            if k % 10 == 0:
                la, lo, al = ltp.to_lla(east, north, 0.0)
                fix.header.stamp = steer.header.stamp
                fix.latitude, fix.longitude, fix.altitude = float(la), float(lo), float(al)
                calls.append((on_fix, fix))
            total = 0.0
            cpu0 = time.thread_time()
            for callback, msg in calls:
                start = time.perf_counter()
                callback(msg)
                dt = time.perf_counter() - start
                total += dt
                if k >= skip_s * 100:
                    wall.append(dt)
            if k >= skip_s * 100:
                tick.append(total)
                tick_cpu.append(time.thread_time() - cpu0)
        learning = node.stiffness is not None and node.stiffness.estimate().active
        node.destroy_node()
    finally:
        rclpy.shutdown()
    ms, tick_ms = np.asarray(wall) * 1e3, np.asarray(tick) * 1e3
    cpu_ms = np.asarray(tick_cpu) * 1e3
    return {"callbacks": int(ms.size), "p50_ms": float(np.median(ms)),
            "p99_ms": float(np.quantile(ms, 0.99)), "max_ms": float(ms.max()),
            "tick_p50_ms": float(np.median(tick_ms)),
            "tick_p99_ms": float(np.quantile(tick_ms, 0.99)),
            "tick_cpu_mean_ms": float(cpu_ms.mean()),
            "tick_cpu_p50_ms": float(np.median(cpu_ms)),
            "tick_cpu_p99_ms": float(np.quantile(cpu_ms, 0.99)),
            "stiffness_learning_at_end": bool(learning)}  # fmt: skip


def _cpu_s(stat: Path) -> float:
    """User plus system CPU time in a Linux ``/proc`` ``stat`` file, s."""
    fields = stat.read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _process_cpu_s(pid: int) -> float:
    """User plus system CPU time of process ``pid`` so far, s."""
    return _cpu_s(Path(f"/proc/{pid}/stat"))


def _thread_cpu_s(pid: int) -> dict[str, float]:
    """CPU time of the threads of process ``pid`` so far by thread name, s: the main thread
    (the Python callbacks) as ``main``, the middleware's threads under their own names."""
    out: dict[str, float] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        name = "main" if task.name == str(pid) else (task / "comm").read_text().strip()
        out[name] = out.get(name, 0.0) + _cpu_s(task / "stat")
    return out


def node_keepup(
    bag: Path,
    rate: float,
    stiffness: bool = True,
    n_particles: int = 300,
    params: tuple[str, ...] = (),
) -> dict[str, Any]:
    """Whether ``estimator_node`` (its own process, ``use_sim_time``, reliable QoS, every
    estimator on unless ``stiffness`` False; ``params``: more ``name:=value`` parameters)
    keeps up with ``bag`` played over DDS at ``rate`` times real time by
    :class:`~tire_estimation.nodes.bag_player.BagPlayer` in this process, as
    tests/nodes/test_integration_dds.py plays it. After the play and a 3 s pause one more
    ``/clock`` 2 s of bag time on makes the node publish its final ``/diagnostics``.

    Returns, from that report: ``received_pct`` (messages the node received over those in the
    bag, per input stream), ``late`` (samples processed out of stamp order because they
    arrived behind the wheel speeds) and ``dropped`` (every drop counter, e.g. stale fixes);
    with ``play_wall_s``, and the CPU time during the play, s: of the node process, of its
    threads by name (``main``: the Python callbacks) and of this process (player and
    listener)."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosbags.rosbag2 import Reader
    from rosgraph_msgs.msg import Clock

    from tire_estimation.bag.reader import read_bag
    from tire_estimation.bag.topics import INPUT_STREAMS
    from tire_estimation.nodes.bag_player import BagPlayer

    exe = shutil.which("estimator_node")
    if exe is None:
        return {"error": "estimator_node not on PATH (source env.sh)"}
    counts = {k: v.count for k, v in read_bag(bag, topics=[]).topics.items()}
    with Reader(bag) as reader:
        end_ns = int(reader.end_time)
    proc = subprocess.Popen(
        [exe, "--ros-args", "-p", "use_sim_time:=true",
         "-p", f"vehicle_file:={bag / 'vehicle.yaml'}", "-p", "persistence_file:=''",
         "-p", "sensor_qos:=reliable", "-p", f"radius.n_particles:={n_particles}",
         "-p", f"stiffness_enabled:={str(stiffness).lower()}",
         *(arg for param in params for arg in ("-p", param)), "--log-level", "warn"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=os.environ.copy(),
    )  # fmt: skip
    context = rclpy.Context()
    rclpy.init(context=context)
    reports: list[Any] = []
    executor = SingleThreadedExecutor(context=context)
    try:
        listener = rclpy.create_node("keepup_listener", context=context)
        listener.create_subscription(DiagnosticArray, "/diagnostics", reports.append, 10)
        executor.add_node(listener)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        player = BagPlayer(bag, context=context)
        deadline = time.monotonic() + 30.0
        while listener.count_subscribers("/vehicle/wheel_speeds") < 1:
            if time.monotonic() > deadline or proc.poll() is not None:
                return {"error": "estimator_node did not subscribe"}
            time.sleep(0.2)
        time.sleep(1.0)
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        threads0 = _thread_cpu_s(proc.pid)
        node_cpu0, own_cpu0, wall0 = _process_cpu_s(proc.pid), time.process_time(), time.time()
        player.play(rate=rate, qos=reliable)
        play_wall_s = time.time() - wall0
        node_cpu_s = _process_cpu_s(proc.pid) - node_cpu0
        threads = _thread_cpu_s(proc.pid)
        node_threads = {
            k: round(v - threads0.get(k, 0.0), 2)
            for k, v in threads.items()
            if v > threads0.get(k, 0.0)
        }
        own_cpu_s = time.process_time() - own_cpu0
        time.sleep(3.0)
        n_reports = len(reports)
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = divmod(end_ns + 2_000_000_000, 1_000_000_000)
        player.clock_pub.publish(clock)
        deadline = time.monotonic() + 5.0
        while len(reports) == n_reports and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
        executor.shutdown()
        rclpy.shutdown(context=context)
        spinner.join(timeout=5.0)
    values = {
        kv.key: kv.value
        for arr in reports[-1:]
        for st in arr.status
        if st.name == "tire_estimation: radius estimator"
        for kv in st.values
    }
    received = {
        stream: round(100.0 * int(values.get(f"received.{stream}", 0)) / counts[topic], 2)
        for topic, stream in INPUT_STREAMS.items()
        if counts.get(topic)
    }
    late = {k[5:]: int(v) for k, v in values.items() if k.startswith("late.")}
    dropped = {k[8:]: int(v) for k, v in values.items() if k.startswith("dropped.")}
    return {"rate": rate, "stiffness": stiffness, "load": os.getloadavg()[0],
            "received_pct": received, "late": late, "dropped": dropped,
            "play_wall_s": round(play_wall_s, 2), "node_cpu_s": round(node_cpu_s, 2),
            "node_threads_cpu_s": node_threads, "player_cpu_s": round(own_cpu_s, 2)}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Run all benchmarks and print JSON."""
    parser = argparse.ArgumentParser(description="tire_estimation benchmarks")
    parser.add_argument("--particles", type=int, nargs="+", default=[100, 500, 2000])
    parser.add_argument(
        "--per-sample-particles",
        type=int,
        nargs="+",
        default=[100, 200, 500],
        help="N of the side-by-side per-sample costs of the radius and the stiffness MPF",
    )
    parser.add_argument("--latency-seconds", type=float, default=20.0)
    parser.add_argument("--skip-node", action="store_true", help="no DDS latency benchmark")
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    parser.add_argument(
        "--replay-bag",
        type=Path,
        default=DEMO_BAG,
        help="bag of the replay benchmark (default: the bundled 6-minute bag; the issue's "
        "25-minute figure: `tire-estimation simulate ece_r64 --minutes 25 --seed 1 --sensor "
        "tire_force_enabled=false --out BAG`)",
    )
    parser.add_argument(
        "--memory-bags",
        type=Path,
        nargs="+",
        default=[DEMO_BAG],
        help="bags of the replay's peak-memory figure, shortest first (default: the bundled "
        "6-minute bag; the issue's figures: `tire-estimation simulate ece_r64 --minutes M "
        "--seed 1 --out BAG` for M = 10 and 240)",
    )
    args = parser.parse_args(argv)
    results: dict[str, Any] = {"machine": {"cpus": os.cpu_count(), "load": os.getloadavg()}}
    results["step_time"] = {str(n): step_time_us(n) for n in args.particles}
    results["stiffness_step_time"] = {str(n): stiffness_step_time_ms(n) for n in args.particles}
    results["per_sample"] = per_sample_costs(args.per_sample_particles)
    results["replay"] = {str(n): replay_rtf(n, args.replay_bag) for n in args.particles}
    # the default replay: every estimator (stiffness MPF and its linear-KF baseline included)
    results["replay_default"] = replay_rtf(None, args.replay_bag, stiffness=True)
    results["imu_estimators"] = imu_estimator_costs(args.replay_bag)
    results["tyre_force"] = tyre_force_costs(args.replay_bag)
    results["replay_memory"] = memory_against_length(args.memory_bags)
    if not args.skip_node:
        results["node_callback"] = node_callback_time()
        results["node_latency"] = node_latency(args.latency_seconds)
    text = json.dumps(results, indent=1)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
