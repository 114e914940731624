"""The core on a CUDA device (`mate.core.device`), measured on a GPU: speed, and how its transitions differ from the
CPU core's.

    python benchmarks/gpu.py [--batch-sizes 4096 16384 65536] [--seconds 5] [--json benchmarks/results/gpu.json]

1. **Same game.** B = 256 games of MATE-4v8-9 and of MATE-8v8-9 reset from the same seeds and stepped 300 times with
   the same random actions on the device and on the CPU core: per step, the largest absolute difference of the
   observations and of every float array of the world, and how many games have left the CPU's trajectory (any
   integer or boolean array of the world different: a target that delivered on one side and not on the other, a
   tracked flag, an episode end). The device's math library rounds sin, cos, atan2 and sqrt to within an ulp or
   two of the CPU's, so float64 games agree to the last bits until a comparison lands on the other side.
2. **Speed.** env-steps/s of the device core (random actions from a bank of 64 pre-drawn steps on the device,
   observations built every step, float64 and float32 observations) at each batch size, timed over `--seconds`
   after a warm-up, with the device synchronised.
3. **The whole game.** env-steps/s of `make_vec(..., device='cuda')` with both teams greedy on the device
   (`mate.teams.device`: observe, messages, act, the step, autoreset; nothing on the host) at each batch size, and
   of greedy cameras against random targets.
4. **Greedy vs greedy.** 300 games of MATE-4v8-9 (seeds 0-299), greedy teams on the device, each to the end of its
   first episode: the mean episode coverage rate and its standard error, beside the CPU teams' on the same seeds
   (`play_batch`); the issue's bar is a difference within 3 standard errors.
5. **Rollouts.** Decisions/s of one team's rollout on the device (`rollout`: HRL cameras with the executor kernel,
   or targets, against the greedy device team, a 256-256 MLP deciding every 5 env steps on the GPU): the trainers'
   collection without their learning step.
6. **Training end to end.** Decisions/s of `mate train mappo` with `--device cuda --game-device cuda`
   (`TrainingEnv(..., device='cuda')`: the games, the greedy opponent, the features and the HRL executor on the
   GPU): HRL-MAPPO cameras on MATE-4v8-9 and MAPPO targets on MATE-2v4-0, at 2,048 and 16,384 envs, timed between the
   end of the first iteration (compilation, warm-up) and the first one `--train-seconds` later (the run then stops
   as at Ctrl-C), and the minutes 10 M decisions take at that rate.

Writes a JSON record (the device, the versions, every number; rewritten after every measurement) and prints one
line per measurement; about 8 minutes on one H200 with the defaults (not yet timed there: `--seconds 2
--train-seconds 15` if time is short, as `benchmarks/gpu_session.sh` does). Needs a CUDA GPU and the gpu extra
(`pip install -e '.[gpu]'`).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import time
from pathlib import Path

import numpy as np

from mate.config import read_config
from mate.core import engine
from mate.core.device import DeviceCore, cuda_module
from mate.core.params import params_from_config
from mate.core.world import empty_world
from mate.spaces import camera_observation_space_of, target_observation_space_of


def dims_of(p) -> tuple[int, int]:
    counts = (p.num_cameras, p.num_targets, p.num_obstacles)
    return camera_observation_space_of(*counts).shape[0], target_observation_space_of(*counts).shape[0]


def same_game(preset: str, batch_size: int = 256, steps: int = 300) -> dict:
    """The device's games beside the CPU core's (module docstring, 1)."""
    p = params_from_config(read_config(preset))
    dims = dims_of(p)
    core = DeviceCore(p, batch_size, dims)
    world, every = empty_world(p, batch_size), np.ones(batch_size, bool)
    camera_obs = np.zeros((batch_size, p.num_cameras, dims[0]))
    target_obs = np.zeros((batch_size, p.num_targets, dims[1]))
    engine.seed_rows(world, every, range(batch_size))
    engine.reset(p, world, every, camera_obs, target_obs)
    core.reset(seeds=range(batch_size))
    rng = np.random.default_rng(0)
    worst_obs, worst_world, parted = [], [], []
    for _ in range(steps):
        camera_actions = rng.uniform(-30, 30, (batch_size, p.num_cameras, 2))
        target_actions = rng.uniform(-30, 30, (batch_size, p.num_targets, 2))
        engine.step(p, world, camera_actions, target_actions, camera_obs, target_obs)
        core.step(camera_actions, target_actions)
        host = core.world_to_host()
        worst_obs.append(max(float(np.abs(camera_obs - core.camera_obs.copy_to_host()).max()),
                             float(np.abs(target_obs - core.target_obs.copy_to_host()).max())))
        floats = [np.abs(a - b).max() for a, b in zip(world, host) if a.dtype.kind == 'f' and a.size]
        worst_world.append(float(max(floats)))
        apart = np.zeros(batch_size, bool)
        for a, b in zip(world, host):
            if a.dtype.kind in 'biu' and a.size:
                apart |= (a != b).reshape(batch_size, -1).any(axis=1)
        parted.append(int(apart.sum()))
    return dict(preset=preset, batch_size=batch_size, steps=steps, max_obs_difference=max(worst_obs),
                max_world_float_difference=max(worst_world), games_apart_at_end=parted[-1],
                first_step_with_a_game_apart=next((i + 1 for i, n in enumerate(parted) if n), None))


def speed(preset: str, batch_size: int, seconds: float, dtype) -> dict:
    """env-steps/s of the device core (module docstring, 2)."""
    cuda = cuda_module()
    p = params_from_config(read_config(preset))
    core = DeviceCore(p, batch_size, dims_of(p), dtype=dtype)
    core.reset(seeds=range(batch_size))
    rng = np.random.default_rng(0)
    bank = [(cuda.to_device(rng.uniform(-30, 30, (batch_size, p.num_cameras, 2))),
             cuda.to_device(rng.uniform(-30, 30, (batch_size, p.num_targets, 2)))) for _ in range(64)]
    for camera_actions, target_actions in bank[:8]:                  # compile and warm up
        core.step(camera_actions, target_actions)
    cuda.synchronize()
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for camera_actions, target_actions in bank:
            core.step(camera_actions, target_actions)
        cuda.synchronize()
        steps += len(bank)
    elapsed = time.perf_counter() - start
    return dict(preset=preset, batch_size=batch_size, dtype=np.dtype(dtype).name, steps=steps, seconds=elapsed,
                env_steps_per_second=steps * batch_size / elapsed)


class TwoTeams:
    """Both teams played on the device by `DeviceRuleTeam`s against each other in the device env (the loop a
    researcher writes for two `mate.teams` teams on the CPU): `step()` plays one env step of every game and
    returns (terminated, truncated, infos)."""

    def __init__(self, env, camera_agent: str, target_agent: str, seed: int = 0) -> None:
        import torch

        from mate.teams.device import DeviceRuleTeam

        self.env = env
        B = env.num_envs
        self.teams = (DeviceRuleTeam(camera_agent, 'camera', B, env.counts, seed=seed),
                      DeviceRuleTeam(target_agent, 'target', B, env.counts, seed=seed))
        self.observations, _ = env.reset(seed=seed)
        every = torch.ones(B, dtype=torch.bool, device=self.observations[0].device)
        for team, observation in zip(self.teams, self.observations):
            team.reset(observation, every)
        self.waiting = ~every               # the games that ended at the last step (next_step: they restart now)

    def step(self):
        actions = tuple(team.act(observation) for team, observation in zip(self.teams, self.observations))
        self.observations, _, terminated, truncated, infos = self.env.step_games(actions)
        for team, observation in zip(self.teams, self.observations):
            team.reset(observation, self.waiting)
        self.waiting = terminated | truncated
        return terminated, truncated, infos


def whole_game(preset: str, batch_size: int, seconds: float, target_agent: str = 'greedy') -> dict:
    """env-steps/s of the device env with both teams played on the device (module docstring, 3)."""
    import mate

    cuda = cuda_module()
    env = mate.make_vec('MultiAgentTracking-v0', batch_size, config=preset, device='cuda',
                        observation_dtype=np.float32)
    game = TwoTeams(env, 'greedy', target_agent)
    for _ in range(8):
        game.step()
    cuda.synchronize()
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for _ in range(32):
            game.step()
        cuda.synchronize()
        steps += 32
    elapsed = time.perf_counter() - start
    return dict(preset=preset, batch_size=batch_size, teams=f'greedy vs {target_agent}', steps=steps,
                seconds=elapsed, env_steps_per_second=steps * batch_size / elapsed)


def greedy_statistics(preset: str = 'MATE-4v8-9', seeds: int = 300) -> dict:
    """Greedy vs greedy on the device and on the CPU, the same seeds (module docstring, 4)."""
    import mate
    from mate.teams import GreedyTeam, play_batch

    env = mate.make_vec('MultiAgentTracking-v0', seeds, config=preset, device='cuda')
    game = TwoTeams(env, 'greedy', 'greedy')
    coverage = np.full(seeds, np.nan)
    start = time.perf_counter()
    while np.isnan(coverage).any():
        terminated, truncated, info = game.step()
        done = (terminated | truncated).cpu().numpy() & np.isnan(coverage)
        if done.any():
            coverage[done] = info['episode_coverage_rate'].cpu().numpy()[done]
    device_seconds = time.perf_counter() - start
    episodes, _ = play_batch(read_config(preset), lambda n, c: GreedyTeam('camera', n, c, seed=0),
                             lambda n, c: GreedyTeam('target', n, c, seed=0), episodes=seeds, seed=0)
    cpu = np.array([episode.coverage_rate for episode in episodes])
    se = [float(x.std(ddof=1) / np.sqrt(seeds)) for x in (coverage, cpu)]
    return dict(preset=preset, seeds=seeds, device_mean_coverage_rate=float(coverage.mean()),
                device_standard_error=se[0], cpu_mean_coverage_rate=float(cpu.mean()), cpu_standard_error=se[1],
                difference_in_standard_errors=float((coverage.mean() - cpu.mean()) / np.hypot(*se)),
                device_seconds=device_seconds)


def rollout(team: str, batch_size: int, seconds: float, frame_skip: int = 5, hidden: int = 256) -> dict:
    """Decisions/s of a rollout on the device, the trainers' shape without their learning step (module docstring,
    5): one team's games against the greedy device team, a two-layer MLP (random weights) deciding on the GPU every
    `frame_skip` env steps; HRL cameras (keep bits per target, the executor kernel re-aiming at every env step) or
    targets (continuous moves held for the decision)."""
    import torch

    import mate
    from mate.core.device import from_torch
    from mate.teams.device import hrl_actions

    env = mate.make_team_vec(None, team, batch_size, device='cuda', observation_dtype=np.float32)
    observations, _ = env.reset(seed=0)
    B, N, D = observations.shape
    nt = env.counts[1]
    device = observations.device
    outputs = nt if team == 'camera' else 2
    policy = torch.nn.Sequential(torch.nn.Linear(D, hidden), torch.nn.Tanh(), torch.nn.Linear(hidden, hidden),
                                 torch.nn.Tanh(), torch.nn.Linear(hidden, outputs)).to(device)
    high = torch.as_tensor(env.single_action_space.high, device=device)
    actions = torch.zeros((B, N, 2), dtype=torch.float64, device=device)
    begin = int(mate.spaces.observation_indices_of(mate.Team.CAMERA, *env.counts)[2]) if team == 'camera' else 0

    def decide(observations):
        with torch.no_grad():
            logits = policy(observations)
        if team == 'camera':
            return torch.bernoulli(torch.sigmoid(logits)).bool()
        return torch.tanh(logits).to(torch.float64) * high

    def one_decision(observations):
        decision = decide(observations)
        for _ in range(frame_skip):
            if team == 'camera':
                hrl_actions(from_torch(observations.reshape(B * N, D)), from_torch(decision.reshape(B * N, nt)),
                            begin, from_torch(actions.view(B * N, 2)))
                observations, *_ = env.step_games(actions)
            else:
                observations, *_ = env.step_games(decision)
        return observations

    for _ in range(3):
        observations = one_decision(observations)
    torch.cuda.synchronize() if device.type == 'cuda' else None
    decisions, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        observations = one_decision(observations)
        decisions += 1
        if device.type == 'cuda' and decisions % 8 == 0:
            torch.cuda.synchronize()
    torch.cuda.synchronize() if device.type == 'cuda' else None
    elapsed = time.perf_counter() - start
    return dict(team=team, batch_size=batch_size, frame_skip=frame_skip, decisions=decisions * B, seconds=elapsed,
                decisions_per_second=decisions * B / elapsed,
                env_steps_per_second=decisions * B * frame_skip / elapsed)


def training(team: str, batch_size: int, seconds: float, device: str = 'cuda') -> dict:
    """Decisions/s of a MAPPO run with the game on the device (module docstring, 6): HRL cameras (MATE-4v8-9) or
    targets (MATE-2v4-0), the trainer's defaults otherwise, `batch_size` envs, timed from the end of its first
    iteration for about `seconds`; the networks on `device` (the games always on the GPU)."""
    import tempfile

    from mate.learn.mappo import MAPPOConfig, train

    marks = []

    def mark(row):       # stop (as Ctrl-C does: after this iteration) once `seconds` have passed since the first one
        marks.append((time.perf_counter(), int(row['env_steps'])))
        if marks[-1][0] - marks[0][0] >= seconds:
            os.kill(os.getpid(), signal.SIGINT)

    with tempfile.TemporaryDirectory() as run_dir:
        config = MAPPOConfig(team=team, hrl=team == 'camera', num_envs=batch_size, device=device, game_device='cuda',
                             steps=10 ** 10, progress=False, run_dir=run_dir, fresh=True,
                             checkpoint_every=10 ** 6)
        started = time.perf_counter()
        train(config, callback=mark)
    (t0, s0), (t1, s1) = marks[0], marks[-1]
    rate = (s1 - s0) / max(t1 - t0, 1e-9)
    return dict(team=team, hrl=team == 'camera', batch_size=batch_size, iterations=len(marks),
                first_iteration_seconds=t0 - started, decisions=s1 - s0, seconds=t1 - t0, decisions_per_second=rate,
                minutes_for_10M=1e7 / rate / 60 if rate else None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--batch-sizes', type=int, nargs='+', default=[4096, 16384, 65536])
    parser.add_argument('--seconds', type=float, default=5.0)
    parser.add_argument('--presets', nargs='+', default=['MATE-4v8-9', 'MATE-8v8-9'])
    parser.add_argument('--train-seconds', type=float, default=25.0)
    parser.add_argument('--train-batch-sizes', type=int, nargs='+', default=[2048, 16384])
    parser.add_argument('--json', default='benchmarks/results/gpu.json')
    args = parser.parse_args()
    cuda = cuda_module()
    gpu = cuda.get_current_device()
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)

    def save() -> None:      # after every measurement: a run cut short by its time limit keeps what it measured
        path.write_text(json.dumps(record, indent=1) + '\n')

    record = dict(device=gpu.name.decode() if isinstance(gpu.name, bytes) else str(gpu.name),
                  compute_capability=list(gpu.compute_capability), cpu=platform.processor(),
                  numba_cuda=__import__('numba_cuda').__version__, same_game=[], speed=[])
    for preset in args.presets:
        found = same_game(preset)
        record['same_game'].append(found)
        save()
        print(f"{preset}: obs differ by at most {found['max_obs_difference']:.3g}, world floats by "
              f"{found['max_world_float_difference']:.3g}; {found['games_apart_at_end']} of {found['batch_size']} "
              f"games apart after {found['steps']} steps (first at step {found['first_step_with_a_game_apart']})",
              flush=True)
    for preset in args.presets:
        for dtype in (np.float64, np.float32):
            for batch_size in args.batch_sizes:
                found = speed(preset, batch_size, args.seconds, dtype)
                record['speed'].append(found)
                save()
                print(f"{preset} B={batch_size} {found['dtype']}: {found['env_steps_per_second']:,.0f} env-steps/s",
                      flush=True)
    def measure(section: str, calls, line) -> None:     # each call's record, saved, and its line printed
        record[section] = []
        for call in calls:
            found = call()
            record[section].append(found)
            save()
            print(line(found), flush=True)

    measure('whole_game', [lambda agent=agent, b=b: whole_game('MATE-4v8-9', b, args.seconds, agent)
                           for agent in ('greedy', 'random') for b in args.batch_sizes],
            lambda found: f"MATE-4v8-9 {found['teams']} on the device, B={found['batch_size']}: "
                          f"{found['env_steps_per_second']:,.0f} env-steps/s")
    measure('rollout', [lambda team=team, b=b: rollout(team, b, args.seconds)
                        for team in ('camera', 'target') for b in args.batch_sizes],
            lambda found: f"rollout of {'HRL cameras' if found['team'] == 'camera' else 'targets'} vs greedy on the "
                          f"device, B={found['batch_size']}: {found['decisions_per_second']:,.0f} decisions/s")
    measure('training', [lambda team=team, b=b: training(team, b, args.train_seconds)
                         for team in ('camera', 'target') for b in args.train_batch_sizes],
            lambda found: f"mate train mappo {'--hrl cameras' if found['team'] == 'camera' else 'targets'}, game on "
                          f"the device, B={found['batch_size']}: {found['decisions_per_second']:,.0f} decisions/s "
                          f"({found['iterations']} iterations; 10 M decisions in {found['minutes_for_10M'] or 0:.1f} "
                          'min)')
    found = record['greedy_statistics'] = greedy_statistics()
    print(f"greedy vs greedy, {found['seeds']} seeds: device {found['device_mean_coverage_rate']:.4f} "
          f"+- {found['device_standard_error']:.4f}, CPU {found['cpu_mean_coverage_rate']:.4f} "
          f"+- {found['cpu_standard_error']:.4f} ({found['difference_in_standard_errors']:+.2f} SE)", flush=True)
    save()
    print(f'written to {args.json}')


if __name__ == '__main__':
    main()
