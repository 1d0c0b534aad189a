"""odocal: odometry calibration and test-track design for differential-drive robots."""

__version__ = "0.1.0"
