"""Tests of odocal.calibration, one file per module (test_<module>.py)."""
