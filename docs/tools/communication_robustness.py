"""How communicating policies hold up when the channel degrades: each policy played over the same seeds with an
ideal channel, with message dropout and with a restricted communication range, plus the messages per step.

    python docs/tools/communication_robustness.py --team target --config MATE-4v8-0 \\
        results/runs/mappo-target-4v8-0-tarmac-seed*/final.pt --json robustness.json
    python docs/tools/communication_robustness.py --team camera results/runs/mappo-hrl-tarmac-camera-4v8-9-seed0/final.pt

Each policy (`checkpoint:PATH`, or any agent spec of `mate evaluate` such as `pretrained:NAME`) plays E episodes
(episode i: seed + i, the single agents talking through the env's channel with `mate.group_step`) against the
Python greedy agents of the other team, once per channel: `dropout P` puts `RandomMessageDropout(P)` between the
agents and the env, `range R` puts `RestrictedCommunicationRange(R)` there (R world units; the terrain is 2000
across). A `RenderCommunication` wrapper outside the filter counts the trained team's messages: `sent` per raw
step (a broadcast once, requests and replies each once) and `delivered` per raw step (copies that reached a
teammate after the filter, a broadcast's copy to its sender left out). The score is the team's metric: coverage
rate for cameras, normalised target return for targets (mean and std over episodes). Prints a markdown table;
`--json OUT` writes every row.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

import mate
from mate.cli.main import ArgumentParser
from mate.evaluation.evaluate import play_episode, resolve_agent
from mate.messages import Team

METRIC = {'camera': 'coverage_rate', 'target': 'normalized_target_return'}


class MessageCount:
    """`play_episode`'s `on_step`: the trained team's messages sent and delivered, summed over the episode's steps
    (read from the `RenderCommunication` wrapper, the outermost)."""

    def __init__(self, team: Team) -> None:
        self.team, self.sent, self.delivered, self.steps = team, 0, 0, 0

    def __call__(self, env, step: int, joint_action) -> None:
        if step == 0:
            return
        self.sent += int(sum(counts.sum() for counts in env.sent[self.team].values()))
        self.delivered += int(sum(counts.sum() for counts in env.received[self.team].values()))
        self.steps = step


def channel_env(config: str, channel: tuple[str, float]):
    """The env of one channel setting: ('ideal', 0), ('dropout', P) or ('range', R), under a message counter."""
    kind, value = channel
    env = mate.make('MultiAgentTracking-v0', config=config)
    if kind == 'dropout' and value > 0:
        env = mate.RandomMessageDropout(env, value)
    elif kind == 'range':
        env = mate.RestrictedCommunicationRange(env, value)
    return mate.RenderCommunication(env, duration=1)


@functools.lru_cache(maxsize=None)
def teams(policy: str, team: str) -> tuple:
    """(camera factory, target factory): the policy for `team`, greedy for the other; a checkpoint is loaded once
    for all the channels it plays."""
    trained = Team.CAMERA if team == 'camera' else Team.TARGET
    own = resolve_agent(f'checkpoint:{policy}' if Path(policy).is_file() else policy, trained)
    other = resolve_agent('greedy', Team.TARGET if team == 'camera' else Team.CAMERA)
    return (own, other) if team == 'camera' else (other, own)


def score(policy: str, team: str, config: str, channel: tuple[str, float], episodes: int, seed: int,
          max_steps: int) -> dict:
    """One row: the policy's metric (mean, std over episodes) and messages per raw step on one channel."""
    trained = Team.CAMERA if team == 'camera' else Team.TARGET
    cameras, targets = teams(policy, team)
    env = channel_env(config, channel)
    values, sent, delivered, steps = [], 0, 0, 0
    start = time.perf_counter()
    for episode in range(episodes):
        count = MessageCount(trained)
        result = play_episode(env, lambda seed: cameras(seed=seed), lambda seed: targets(seed=seed), seed + episode,
                              max_steps, count)
        values.append(getattr(result, METRIC[team]))
        sent, delivered, steps = sent + count.sent, delivered + count.delivered, steps + count.steps
    kind, value = channel
    return dict(policy=policy, channel=kind, value=value, mean=float(np.mean(values)), std=float(np.std(values)),
                episodes=episodes, sent_per_step=sent / steps, delivered_per_step=delivered / steps,
                seconds=round(time.perf_counter() - start, 1))


def markdown(rows: list[dict], team: str) -> str:
    label = {'camera': 'coverage rate', 'target': 'normalised target return'}[team]
    lines = [f'| policy | channel | {label} | messages sent / step | delivered / step |', '|---|---|---|---|---|']
    for r in rows:
        channel = {'ideal': 'ideal', 'dropout': f'dropout {r["value"]:g}', 'range': f'range {r["value"]:g}'}[r['channel']]
        lines.append(f'| {r["policy"]} | {channel} | {r["mean"]:.3f} ± {r["std"]:.3f} | {r["sent_per_step"]:.2f} '
                     f'| {r["delivered_per_step"]:.2f} |')
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('policies', nargs='+', help='checkpoint paths or agent specs of the trained team')
    parser.add_argument('--team', choices=('camera', 'target'), required=True)
    parser.add_argument('--config', default='MATE-4v8-9', help='preset or config file (default MATE-4v8-9)')
    parser.add_argument('--episodes', type=int, default=10, help='episodes per policy and channel (default 10)')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--max-episode-steps', type=int, default=2000)
    parser.add_argument('--dropout', type=float, nargs='+', default=[0.0, 0.25, 0.5],
                        help='dropout probabilities in [0, 1] (default 0 0.25 0.5; 0 is the ideal channel)')
    parser.add_argument('--range', type=float, nargs='*', default=[500.0],
                        help='communication ranges in world units > 0 (default 500)')
    parser.add_argument('--json', type=Path, default=None, help='also write the rows to this JSON file')
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.max_episode_steps < 1:
        parser.error(f'--episodes and --max-episode-steps must be >= 1, got {args.episodes} and {args.max_episode_steps}')
    bad = [p for p in args.dropout if not 0.0 <= p <= 1.0] + [r for r in args.range if not r > 0]
    if bad:
        parser.error(f'dropout must be in [0, 1] and range > 0 (world units); got {bad}')
    channels = [('ideal' if p == 0 else 'dropout', p) for p in args.dropout] + [('range', r) for r in args.range]
    rows = []
    for policy in args.policies:
        for channel in channels:
            rows.append(score(policy, args.team, args.config, channel, args.episodes, args.seed,
                              args.max_episode_steps))
            print(f'{policy} {channel}: {rows[-1]["mean"]:.3f} ({rows[-1]["seconds"]} s)', file=sys.stderr, flush=True)
    print(markdown(rows, args.team))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(dict(team=args.team, config=args.config, episodes=args.episodes,
                                             seed=args.seed, max_episode_steps=args.max_episode_steps, rows=rows),
                                        indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
