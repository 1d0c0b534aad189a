"""Tests of odocal.plot, one file per module (test_<module>.py)."""
