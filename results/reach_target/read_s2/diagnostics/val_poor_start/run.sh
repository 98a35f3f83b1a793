#!/bin/bash
# BENCHMARKS 23's open question, on the val split (no test episode is used): does READ seed 0 (read_s2)
# recover from the oracle's 500th neighbour with the paper's renoise update, or the cold update without anchor?
cd /work/main
R=runs/reach_target/read_s2
for args in "--no-refine" "--N 100 --refine cold_anchor --rounds 2" "--N 100 --refine renoise --rounds 1" "--N 100 --refine cold --rounds 1" "--N 100 --refine renoise --rounds 2"; do
  nice -n 5 .venv/bin/python -m experiments.evaluate --run $R --split val --retrieval cheat --rank 500 $args --videos 0 --quiet
done
