"""Comparing campaigns: parameters over time, drift and the sensors' agreement (`comparison`), the
same by what calibrations predict (`predictions`), and what each calibration is worth on the robot's
other campaigns (`transfer`)."""
