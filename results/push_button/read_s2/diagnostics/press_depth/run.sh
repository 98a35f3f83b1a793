#!/bin/bash
# PB: the signed depth of each plan's press against the ground truth's, by outcome (BENCHMARKS 27).
# Re-plans the test episodes of an evaluation with its own eval_config (seed, batch, N, update, rounds),
# so the plans are the evaluated ones; the outcomes are the evaluation's. Run from the repository root.
for name in spe_N100 spe_N0; do PYTHONPATH=. python results/push_button/read_s2/diagnostics/press_depth/press_depth.py $name; done
