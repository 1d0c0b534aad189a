"""Tests of odocal.design, one file per module (test_<module>.py)."""
