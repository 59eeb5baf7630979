"""Evaluation: drive the core over recorded streams, compute metrics, draw plots.

No ROS and no rosbags here either: :mod:`tire_estimation.replay` reads the bag and hands the
streams to :func:`runner.run_radius_estimator`.
"""
