"""Analyses of measurements: pure functions on Datasets/DataArrays (paper §4)."""
