"""tire_estimation: online tire radius and stiffness estimation for ROS 2."""

__version__ = "0.1.0"
