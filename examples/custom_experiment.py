"""Your own experiment in the benchmark: the PPO of `own_policy_ppo.py` beside mate's MAPPO, on a tiny budget.

    mate benchmark run examples/custom_experiment.py --out runs/custom          # from any folder; 14 min measured
    mate benchmark report runs/custom --out runs/custom-report                  # results.md, results.json, marl_eval

Measured on two cores shared with other jobs: 14 min for the 14 jobs (the 4 references 0.8 min, my PPO's runs
0.2-0.3 min each, mate's MAPPO runs 0.9-3.2 min each, as the machine's load varied), 2.6 s for the report.

The benchmark plays the references (random, greedy, the upper-bound cameras, and a scripted team of this file) on the
held-out games, runs every (setting, seed) job, scores each run's policy with the protocol (`mate.score_policy`),
and the report judges the claims below. `train_for_benchmark` takes the experiment's `protocol`, so its runs log an
evaluation every `eval_every` decisions: the curves of the report. Five seeds, because a claim between two settings
needs them here: with 3 runs a side the exact rank test can never reach 5 %, and Holm's correction over the three
claims asks for 5 (building the experiment with fewer warns). At 10,000 decisions neither learner is near the greedy
cameras: raise `steps` for a real comparison.
"""

import numpy as np
from own_policy_ppo import train_for_benchmark    # the file beside this one (the benchmark imports it from here)

from mate.benchmark.experiments import Claim, Experiment, Reference, Setting


def sweeping_cameras(observations: np.ndarray) -> np.ndarray:
    """A scripted team, played as a reference (once, no training): every camera turns at its full rate (5 degrees
    per step) and keeps its zoom. Observations (B, N, D) -> actions (B, N, 2): rotation, zoom change."""
    actions = np.zeros((*observations.shape[:2], 2))
    actions[..., 0] = 5.0
    return actions


EXPERIMENT = Experiment(
    'custom-ppo-vs-mappo', 'my PPO beside mate\'s MAPPO (a tiny budget)', 'camera', ('MATE-4v8-9',),
    (Setting('my PPO', call=train_for_benchmark),
     Setting('MAPPO', 'mappo', ('--num-envs', '16', '--rollout-length', '64'))),
    steps=10_000, eval_every=3_500, eval_episodes=4, seeds=5,
    references=('random', 'greedy', 'upper-bound', Reference('sweeping cameras', call=sweeping_cameras)),
    claim='a CleanRL-style PPO and mate\'s MAPPO learn alike on a tiny budget',
    claims=(Claim('my PPO cameras cover more than the random cameras', 'my PPO', 'random'),
            Claim('my PPO cameras cover more than the sweeping cameras', 'my PPO', 'sweeping cameras'),
            Claim('MAPPO cameras cover more than my PPO ones', 'MAPPO', 'my PPO')))
