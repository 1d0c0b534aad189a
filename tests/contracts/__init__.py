"""Contracts across the package: the import layers, fuzzed and boundary inputs and outputs, bad
inputs, and review-style re-derivations of the math."""
