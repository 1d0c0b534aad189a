"""Tests of odocal.app on the typed results its functions return (no argv strings), one file
per module (test_<module>.py)."""
