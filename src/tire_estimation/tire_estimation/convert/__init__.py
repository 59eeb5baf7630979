"""Measured data sets -> contract bags (``tire-estimation convert ...``).

Modules: :mod:`.comma2k19` (a comma2k19 segment: CAN wheel speeds and steering, device IMU,
u-blox GNSS, post-processed reference pose), :mod:`.revs250lm` (the Revs Ferrari 250 LM
lateral-dynamics export: steering, yaw rate, accelerations, INS velocities as reference),
:mod:`.husky` (robot_localization's Clearpath Husky ROS 1 bag: skid-steer side speeds from
the drive controller's odometry, IMU, GPS), :mod:`.common` (shared helpers) and :mod:`.cli`
(the sub-commands).
"""
