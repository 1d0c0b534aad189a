"""Tests of odocal.core, one file per module (test_<module>.py)."""
