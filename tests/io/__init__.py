"""Tests of odocal.io, one file per module (test_<module>.py)."""
