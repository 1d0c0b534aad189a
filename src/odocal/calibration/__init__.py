"""The estimators: one calibration method per module (heading-error method, UMBmark, BCPT,
Ivanjko, linear and trajectory least squares, banded wheelbase, Censi et al. relative motions,
SLAM and scan-matching intervals, gyro, noise, squares; skid-steer models in skid_steer), the
checks around them (the log check, held-out models, clock offsets), their settings and their
result types."""
