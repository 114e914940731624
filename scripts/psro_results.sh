#!/usr/bin/env bash
# The population-training results of docs/population.md: PSRO-Nash, FSP and SP on MATE-2v4-0 at equal
# budget (5 iterations, 40,000 decision steps per best response, 40 episodes per payoff entry, natural
# episode ends), seeds 0-2, then the fixed-opponent comparison (greedy cameras and the shipped MAPPO
# targets, each against a best response of 200,000 steps: the training a PSRO side's newest policy has
# had after 5 warm-started iterations). Every run resumes if started again. ~1 h 50 min on 2 cores.
# Then: python scripts/psro_table.py $OUT --json scripts/results/psro/psro-results.json (the tables), and
# python scripts/psro_final_exploitability.py $OUT/nash-seed0 --br-steps 200000 (the fixed-pair probe of a
# final population, ~7 min).
set -euo pipefail
OUT=${OUT:-runs/psro-results}
COMMON="--config MATE-2v4-0 --iterations 5 --br-steps 40000 --eval-episodes 40 --workers 2"
for seed in ${SEEDS:-0 1 2}; do
  for solver in nash uniform last; do
    mate psro $COMMON --solver $solver --seed $seed --out $OUT/$solver-seed$seed
  done
done
mate psro --config MATE-2v4-0 --iterations 1 --br-steps 200000 --eval-episodes 40 --workers 2 --solver last \
  --initial-cameras greedy --initial-targets pretrained:mappo-target-2v4-0 --out $OUT/fixed-greedy-vs-mappo
mate psro plot $OUT/nash-seed* $OUT/uniform-seed* $OUT/last-seed* --out $OUT/plots
