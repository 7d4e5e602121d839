"""Applying a calibration: the calibrated kinematics as predictions at any joint readings
(`prediction`), compensated joint commands and predicted positions with their 95 % bound
(`compensation`, the commands `remaster compensate` and `remaster predict`), and what goes into the
robot: controller offsets, calibrated URDFs and effects (`exports`) and calibrated DH tables
(`dh_table`)."""
