"""Tests of odocal.cli: parsing, printing and exit codes, one file per command module
(test_<module>.py). The numbers a command prints are tested in tests/app on typed results."""
