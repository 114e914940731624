"""Your own experiment in the benchmark: the PPO of `own_policy_ppo.py` beside mate's MAPPO, on a tiny budget.

    mate benchmark run examples/custom_experiment.py --out runs/custom          # ~80 s on 2 cores, from any folder
    mate benchmark report runs/custom --out runs/custom-report                  # results.md, results.json, marl_eval

The benchmark plays the references (random, greedy, and the upper-bound cameras) on the held-out games, runs every
(setting, seed) job, scores each run's policy with the protocol (`mate.score_policy`), and the report judges the
claims below. At 10,000 decisions neither learner is near the greedy cameras: raise `steps` (and `seeds`) for a
real comparison.
"""

from own_policy_ppo import train_for_benchmark    # the file beside this one (the benchmark imports it from here)

from mate.benchmark.experiments import Claim, Experiment, Setting

EXPERIMENT = Experiment(
    'custom-ppo-vs-mappo', 'my PPO beside mate\'s MAPPO (a tiny budget)', 'camera', ('MATE-4v8-9',),
    (Setting('my PPO', call=train_for_benchmark),
     Setting('MAPPO', 'mappo', ('--num-envs', '16', '--rollout-length', '64'))),
    steps=10_000, eval_every=5_000, eval_episodes=4, seeds=3, references=('random', 'greedy', 'upper-bound'),
    claim='a CleanRL-style PPO and mate\'s MAPPO learn alike on a tiny budget',
    claims=(Claim('my PPO cameras cover more than the random cameras', 'my PPO', 'random'),
            Claim('MAPPO cameras cover more than my PPO ones', 'MAPPO', 'my PPO')))
