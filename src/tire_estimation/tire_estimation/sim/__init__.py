"""Vehicle and sensor simulator (pure Python and NumPy; no ROS, no rosbags)."""

from tire_estimation.sim.config import SensorConfig
from tire_estimation.sim.scenarios import SCENARIOS, scenario_defaults
from tire_estimation.sim.simulator import START_TIME_NS, simulate
from tire_estimation.sim.streams import (
    GnssStream,
    ImuStream,
    SimEvent,
    SimResult,
    SteeringStream,
    TireForceStream,
    TruthStream,
    WheelSpeedStream,
)
from tire_estimation.sim.tires import TireModelConfig

__all__ = [
    "SCENARIOS",
    "START_TIME_NS",
    "GnssStream",
    "ImuStream",
    "SensorConfig",
    "SimEvent",
    "SimResult",
    "SteeringStream",
    "TireForceStream",
    "TireModelConfig",
    "TruthStream",
    "WheelSpeedStream",
    "scenario_defaults",
    "simulate",
]
