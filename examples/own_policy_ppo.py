"""PPO for one MATE team in one file, scored with the benchmark's protocol: the way to bring your own algorithm.

    python examples/own_policy_ppo.py --steps 20000                 # cameras vs the greedy targets
    python examples/own_policy_ppo.py --steps 20000 --eval-episodes 4       # a quick score while iterating
    python examples/own_policy_ppo.py --team target --config MATE-2v4-0 --steps 200000

The score costs more than the training at this budget: on two cores shared with other jobs, 20,000 decisions
trained in 6-10 s and the score took 85-125 s the first time, nearly all of it the three references, each playing the
same 32 + 320 games of 2,500 env steps as the policy. They are the same games every run, so their episodes are kept
in `--reference-cache` (default ~/.cache/mate/references, `$MATE_CACHE_DIR/references` when set; 'none' to play
them every time) and the next runs scored in 7 s; `--eval-episodes 4` scores on 4 + 40 of those games (13.5 s
without the cache; noisier: the benchmark's protocol is 32). The output says what the run spent.
`train_for_benchmark` is a setting of `examples/custom_experiment.py`: the benchmark hands it the experiment's
protocol, and it logs an evaluation whenever one falls due (the curve of the report).

Read top to bottom (CleanRL style): the settings, the network, the PPO loop, the score. It uses mate's public API
only: `mate.make_team_vec` (B games of one team, the other team played inside by the greedy rules) and
`mate.score_policy` (the held-out games, the absolute metric and the random/greedy references on the same games,
exactly as `mate benchmark` scores mate's own trainers). Independent PPO with parameter sharing: one actor and one
critic for every agent of the team, each reading its agent's own observation; cameras learn from the coverage rate
of each step (the paper's camera reward), targets each from their own part of the team reward. A decision is made at
every env step (no frame skip). `--run-dir` keeps the run files `mate benchmark report` reads.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import torch
from torch import nn

import mate


@dataclasses.dataclass
class Args:
    steps: int = 200_000            # decision steps of the training, summed over the games
    team: str = 'camera'            # the team trained: 'camera' or 'target'
    config: str = 'MATE-4v8-9'      # the game (a preset name or a YAML path)
    num_envs: int = 16              # games played at once
    rollout: int = 64               # env steps of every game between two updates
    horizon: int = 500              # env steps per training episode
    lr: float = 3e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    epochs: int = 4
    minibatches: int = 4
    clip: float = 0.2
    entropy: float = 0.0
    value_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden: int = 128
    seed: int = 0
    threads: int = 1                # torch threads (1 is fastest on a shared 2-core machine)
    eval_episodes: int = 32         # the protocol's evaluation (the absolute metric plays ten times as many)
    run_dir: str = ''               # where to keep evaluations.jsonl and absolute.json ('' : nowhere)
    reference_cache: str = 'default'  # the references' episodes kept between runs: 'default', a folder, or 'none'


def parse_args() -> Args:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for field in dataclasses.fields(Args):
        parser.add_argument(f'--{field.name.replace("_", "-")}', type=type(field.default), default=field.default)
    return Args(**vars(parser.parse_args()))


class Scaler:
    """Raw observations (..., N, D) -> float32 features in about [-1, 1], from the observation space's bounds."""

    def __init__(self, space) -> None:
        low, high = space.low.astype(np.float64), space.high.astype(np.float64)
        self.bounded = np.isfinite(low) & np.isfinite(high) & (high > low)
        self.low, self.span = np.where(self.bounded, low, 0.0), np.where(self.bounded, high - low, 1.0)

    def __call__(self, observations: np.ndarray) -> torch.Tensor:
        scaled = np.where(self.bounded, 2.0 * (observations - self.low) / self.span - 1.0, observations)
        return torch.as_tensor(np.clip(scaled, -10.0, 10.0), dtype=torch.float32)


def layer(inputs: int, outputs: int, gain: float = np.sqrt(2)) -> nn.Linear:
    linear = nn.Linear(inputs, outputs)
    nn.init.orthogonal_(linear.weight, gain)
    nn.init.zeros_(linear.bias)
    return linear


class Agent(nn.Module):
    """A Gaussian actor (its mean squashed to [-1, 1]) and a critic, shared by every agent of the team."""

    def __init__(self, features: int, hidden: int) -> None:
        super().__init__()
        self.actor = nn.Sequential(layer(features, hidden), nn.Tanh(), layer(hidden, hidden), nn.Tanh(),
                                   layer(hidden, 2, 0.01), nn.Tanh())
        self.critic = nn.Sequential(layer(features, hidden), nn.Tanh(), layer(hidden, hidden), nn.Tanh(),
                                    layer(hidden, 1, 1.0))
        self.log_std = nn.Parameter(torch.full((2,), -0.5))

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def act(self, x: torch.Tensor, action: torch.Tensor | None = None):
        """(action, its log-probability, the entropy, the value) for features x (..., F)."""
        distribution = torch.distributions.Normal(self.actor(x), self.log_std.exp())
        if action is None:
            action = distribution.sample()
        return action, distribution.log_prob(action).sum(-1), distribution.entropy().sum(-1), self.value(x)


def train(args: Args, say=print, protocol=None):
    """Train with PPO; returns (the agent, the observation scaler, the action bounds (N, 2)). With `protocol` (the
    benchmark's, `mate.benchmark.user.RunProtocol`), the policy is evaluated whenever `protocol.due` says: the
    points of the learning curve in the benchmark's report."""
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    reward = 'coverage' if args.team == 'camera' else 'own'
    envs = mate.make_team_vec(args.config, args.team, args.num_envs, reward=reward, max_episode_steps=args.horizon)
    scale, high = Scaler(envs.single_observation_space), envs.single_action_space.high
    B, N, D = envs.observation_space.shape
    agent = Agent(D, args.hidden)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.lr, eps=1e-5)
    T = args.rollout
    obs_buf, act_buf = torch.zeros(T, B, N, D), torch.zeros(T, B, N, 2)
    logp_buf, val_buf, rew_buf, live_buf = (torch.zeros(T, B, N) for _ in range(4))
    cut_buf = torch.zeros(T, B, N)                    # the step ended its episode (by truncation or termination)
    observations, _ = envs.reset(seed=args.seed)
    live = np.ones(B, dtype=bool)                     # next-step autoreset: a step after an episode end is ignored
    iterations = -(-args.steps // (T * B))            # whole iterations: the budget rounded up
    say(f'PPO {args.team}s on {args.config}: {iterations} iterations of {T} x {B} decisions '
        f'({iterations * T * B:,} decision steps)')
    finished, start = [], time.perf_counter()
    for iteration in range(1, iterations + 1):
        for t in range(T):
            x = scale(observations)
            with torch.no_grad():
                action, logp, _, value = agent.act(x)
            observations, rewards, terminations, truncations, infos = envs.step(
                np.clip(action.numpy(), -1.0, 1.0) * high)
            obs_buf[t], act_buf[t], logp_buf[t], val_buf[t] = x, action, logp, value
            rew_buf[t] = torch.as_tensor(rewards.reshape(B, -1), dtype=torch.float32)   # (B, 1) team: to every agent
            live_buf[t] = torch.as_tensor(live, dtype=torch.float32)[:, None]
            ended = terminations | truncations
            cut_buf[t] = torch.as_tensor(ended, dtype=torch.float32)[:, None]
            live = ~ended
            if '_mate_episode' in infos:
                finished += infos['mate_episode']['coverage_rate'][infos['_mate_episode']].tolist()
        with torch.no_grad():                          # GAE; a truncated episode is not bootstrapped (kept simple)
            next_value = agent.value(scale(observations))
            advantages, last = torch.zeros(T, B, N), torch.zeros(B, N)
            for t in reversed(range(T)):
                following = next_value if t == T - 1 else val_buf[t + 1]
                carry = 1.0 - cut_buf[t]
                delta = rew_buf[t] + args.gamma * following * carry - val_buf[t]
                last = delta + args.gamma * args.gae_lambda * carry * last
                advantages[t] = last
            returns = advantages + val_buf
        keep = live_buf.reshape(-1) > 0
        flat = [buffer.reshape(T * B * N, *buffer.shape[3:])[keep]
                for buffer in (obs_buf, act_buf, logp_buf, advantages, returns)]
        size = len(flat[0])
        for _ in range(args.epochs):
            for batch in torch.randperm(size).chunk(args.minibatches):
                x, action, old_logp, advantage, target = (buffer[batch] for buffer in flat)
                _, logp, entropy, value = agent.act(x, action)
                ratio = (logp - old_logp).exp()
                advantage = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
                policy_loss = -torch.min(ratio * advantage, ratio.clamp(1 - args.clip, 1 + args.clip) * advantage)
                loss = (policy_loss.mean() + args.value_coef * ((value - target) ** 2).mean()
                        - args.entropy * entropy.mean())
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimizer.step()
        done = iteration * T * B
        if protocol is not None and protocol.due(done - T * B, done):
            protocol.evaluate(as_policy(agent, scale, high), env_steps=done)   # on the benchmark's evaluation games
        recent = (f'coverage of the last {len(finished[-25:])} training episodes {np.mean(finished[-25:]):.3f}'
                  if finished else 'no training episode finished yet')
        say(f'iteration {iteration}/{iterations}: {iteration * T * B:,} decisions, {recent}, '
            f'{iteration * T * B / (time.perf_counter() - start):,.0f} decisions/s')
    return agent, scale, high


def as_policy(agent: Agent, scale: Scaler, high: np.ndarray):
    """The trained team as the protocol's policy: raw observations (B, N, D) -> actions (B, N, 2), the actor's mean."""
    def policy(observations: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return np.clip(agent.actor(scale(observations)).numpy(), -1.0, 1.0) * high
    return policy


def train_for_benchmark(team: str, config: str, steps: int, seed: int, run_dir: str, protocol):
    """A setting of `mate benchmark run examples/custom_experiment.py`: train, logging the evaluations the
    experiment's `protocol` asks for, and return the policy the benchmark scores."""
    args = Args(steps=steps, team=team, config=config, seed=seed, run_dir=run_dir)   # 1 thread (<= protocol.threads)
    return as_policy(*train(args, protocol=protocol))


if __name__ == '__main__':
    args = parse_args()
    start = time.perf_counter()
    agent, scale, high = train(args)
    trained = time.perf_counter() - start
    cache = {'default': True, 'none': None}.get(args.reference_cache, args.reference_cache)
    score = mate.score_policy(as_policy(agent, scale, high), args.team, args.config, episodes=args.eval_episodes,
                              run_dir=args.run_dir or None, env_steps=args.steps, reference_cache=cache)
    print(f'trained in {trained:.1f} s, scored in {time.perf_counter() - start - trained:.1f} s')
    print(f'held-out score ({score.metric}, {len(score.absolute)} episodes on seeds never trained on):')
    print(f'  PPO {score.absolute_mean:.3f}   ' + '   '.join(f'{name} {value:.3f}'
                                                          for name, value in score.reference_means.items()))
    print(f'  normalised (random 0, greedy 1): {score.normalised("greedy"):.2f}')
