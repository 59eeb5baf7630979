"""Reading and writing contract bags (rosbag2, MCAP) with the pure-Python ``rosbags`` library.

Modules: :mod:`.typestore` (ROS 2 Jazzy types plus ``tire_estimation_msgs``), :mod:`.topics`
(contract topic names and types), :mod:`.messages` (message builders and stamp helpers),
:mod:`.cdr` (bulk CDR encoding/decoding of fixed-layout messages), :mod:`.writer`
(:func:`write_sim_bag`) and :mod:`.reader` (:func:`read_bag`).

Nothing here is imported by :mod:`tire_estimation.core`; import the submodules directly.
"""
