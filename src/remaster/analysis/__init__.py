"""Analysis of fitted calibrations: accuracy at the measured and across the joint space,
prediction and compensation, transfer and comparison between campaigns, calibrated models."""
