"""Demonstration data: resampling, the dataset store, batched generation (the motion format they hold is ``readjax.motion``)."""
