"""Demonstration data: the motion format, resampling, the dataset store, batched generation."""
