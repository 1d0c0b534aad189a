"""Tests of odocal.comparison, one file per module (test_<module>.py)."""
