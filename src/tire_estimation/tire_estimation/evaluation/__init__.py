"""Evaluation: record what the pipeline did, compute metrics, draw plots, run campaigns.

No ROS and no rosbags here either: :mod:`tire_estimation.replay` reads the bag and pushes its
samples into the core pipeline with the recorders of :mod:`.runner` attached.
"""
