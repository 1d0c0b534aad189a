"""odocal's tests: one folder per package of src/odocal (test_<module>.py), plus contracts/,
scenarios/ and support/ (helpers, not tests of the package)."""
