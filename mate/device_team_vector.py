"""`DeviceTeamVecEnv`: B games of one team on a CUDA device, the other team played there too by a device team.

The device form of `mate.SingleTeamVecEnv` (`mate.make_team_vec(..., device='cuda')`), a Gymnasium `VectorEnv` with
its API: the same spaces, reward kinds ('team', 'coverage' and 'difference' for cameras, 'team' and 'own' for
targets), autoreset modes, seeding (`reset(seed=s)`: game i and the opponent's row i with s + i) and infos (the
vector env's keys and masks; `mate_episode` with its mask `_mate_episode` on the steps where games ended;
`same_step`: `final_obs`, the team's last observations (B, N, D) where `_final_obs`, and `final_info`), over
`mate.device_vector.DeviceVecEnv`, with torch tensors on the device in and out. The opponent is a device team,
'greedy' (default) or 'random' (`mate.teams.device`: the CPU teams' rules with their own random streams, so the
games agree with the CPU env's in distribution; with a `HostTeam` opponent on the CPU env they agree game for game,
what the tests check).

`step` reads one scalar back per step (whether a game ended: the keys appear where the CPU env has them);
`step_games`, what the device training env of `mate.learn` and the TorchRL adapter call, reads nothing back: its
infos always hold `mate_episode` and `_mate_episode` (all false where no game ended) beside `coverage_rate`, and
no `final_obs`. The returned tensors are the env's buffers, overwritten by the next step. `state_dict()` holds host
arrays.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gymnasium.vector import VectorEnv
from gymnasium.vector.utils import batch_space

from .core.device import BLOCK
from .device_vector import DeviceVecEnv
from .messages import Team
from .protocol import EPISODE_INFO, checked_reward, paper_config
from .teams.protocol import as_team

__all__ = ['DEVICE_OPPONENTS', 'DeviceTeamVecEnv']

DEVICE_OPPONENTS = ('greedy', 'random')
"""The opponents a device team plays."""
FINAL_KEYS = ('final_obs', '_final_obs', 'final_info', '_final_info')
"""Same-step autoreset's keys of `step_games(keep_final=True)`, which `step` passes on."""


class DeviceTeamVecEnv(VectorEnv):
    """B games of one team against a device team, on a CUDA device (module docstring).

    Args:
        config: a preset name, a YAML/JSON path or a dict (None: the paper's game of the team).
        team: 'camera' or 'target', the team the caller plays.
        num_envs: B.
        opponent: 'greedy' or 'random'; `opponent_options` its options.
        reward: 'team', 'coverage' (cameras), 'own' (targets) or 'difference' (cameras).
        max_episode_steps: the episodes' step cap (None: the config's).
        observation_dtype: np.float64 or np.float32.
        autoreset_mode: 'next_step' (default) or 'same_step'.
        block: threads per CUDA block.
        **overrides: config keys (deep-merged, as for `mate.make_vec`).
    """

    def __init__(self, config: Any = None, team='camera', num_envs: int = 1, *, opponent: str = 'greedy',
                 opponent_options: dict | None = None, reward: str = 'team', max_episode_steps: int | None = None,
                 observation_dtype=np.float64, autoreset_mode: str = 'next_step', block: int = BLOCK,
                 **overrides) -> None:
        import torch
        from gymnasium import spaces

        self.team = as_team(team)
        if opponent not in DEVICE_OPPONENTS:
            raise ValueError(f'on a device the opponent is one of {", ".join(DEVICE_OPPONENTS)}, got {opponent!r}')
        if max_episode_steps is not None:        # (checked with the config: ConfigError unless an integer > 0)
            overrides['max_episode_steps'] = max_episode_steps
        self.config = paper_config(self.team) if config is None else config
        self.reward_kind = checked_reward(self.team, reward)
        side = 'target_agent' if self.team is Team.CAMERA else 'camera_agent'
        options = 'target_options' if self.team is Team.CAMERA else 'camera_options'
        self.vec = DeviceVecEnv(self.config, num_envs, observation_dtype=observation_dtype,
                                autoreset_mode=autoreset_mode, block=block,
                                **{side: opponent, options: opponent_options}, **overrides)
        self.num_envs, self.counts = self.vec.num_envs, self.vec.counts
        self._own = 0 if self.team is Team.CAMERA else 1
        self.num_agents = self.counts[self._own]
        own_box = self.vec.camera_observation_space if self.team is Team.CAMERA else self.vec.target_observation_space
        action_box = self.vec.camera_action_space if self.team is Team.CAMERA else self.vec.target_action_space
        N = self.num_agents
        dtype = np.dtype(observation_dtype)
        self.single_observation_space = spaces.Box(np.tile(own_box.low, (N, 1)).astype(dtype),
                                                   np.tile(own_box.high, (N, 1)).astype(dtype), dtype=dtype)
        self.single_action_space = spaces.Box(np.tile(action_box.low, (N, 1)), np.tile(action_box.high, (N, 1)),
                                              dtype=np.float64)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = {'render_modes': [], 'autoreset_mode': self.vec.autoreset_mode}
        self.render_mode = None
        self._max_reward = float(self.vec.params.max_target_team_episode_reward)
        like = self.vec._rewards[0]
        self._sum = torch.zeros(self.num_envs, dtype=torch.float64, device=like.device)
        self._pending = torch.zeros(self.num_envs, dtype=torch.bool, device=like.device)
        self._started = False

    def reset(self, *, seed: int | None = None, options: dict | None = None, opponent_seed: int | None = None):
        """Start new episodes in every game; returns (observations (B, N, D), infos). `seed` s: game i and the
        opponent's row i are seeded s + i (`opponent_seed` o: the opponent's row i with o + i)."""
        observations, infos = self.vec.reset(seed=seed, options=options, team_seed=opponent_seed)
        self._sum.zero_()
        self._pending.zero_()
        self._started = True
        return observations[self._own], infos

    def restart(self, mask) -> None:
        """The games of `mask` (B,) bool (host) start their next episode now, streams going on, none of them
        waiting for a next_step restart any more (TorchRL's partial reset)."""
        import torch

        mask = np.asarray(mask, bool)
        self.vec.restart(mask)
        self._pending &= ~torch.as_tensor(mask, device=self._pending.device)
        self._sum.masked_fill_(torch.as_tensor(mask, device=self._sum.device), 0.0)

    def _rewards(self, team_rewards, info, live):
        import torch

        zero = torch.zeros((), dtype=torch.float64, device=live.device)
        if self.reward_kind in ('team', 'coverage'):    # a game restarting at this step (next_step) is rewarded 0
            step = team_rewards[self._own] if self.reward_kind == 'team' else info['coverage_rate']
            return torch.where(live, step, zero)
        # each target's part of the team reward, or each camera's difference credit, as the core's step computed it
        parts = self.vec.world_tensor('target_reward_parts' if self.reward_kind == 'own' else 'camera_reward_parts')
        return torch.where(live[:, None], parts, zero)

    def step(self, actions):
        """One env step of every game with the team's `actions` (B, N, 2); returns (observations, rewards,
        terminations, truncations, infos), infos as the CPU single-team env's (module docstring)."""
        observations, rewards, terminated, truncated, fast = self.step_games(actions, keep_final=True)
        infos = self.vec.infos()
        ended = fast[f'_{EPISODE_INFO}']
        if bool(ended.any()):
            infos[EPISODE_INFO], infos[f'_{EPISODE_INFO}'] = fast[EPISODE_INFO], ended
        infos.update({key: fast[key] for key in FINAL_KEYS if key in fast})
        return observations, rewards, terminated, truncated, infos

    def step_games(self, actions, keep_final: bool = False):
        """`step` reading nothing back (module docstring): infos hold `coverage_rate` and `mate_episode` with its
        mask always. `keep_final` (same_step): where games ended, also `final_obs`, `final_info` and their masks."""
        import torch

        if not self._started:
            raise RuntimeError('DeviceTeamVecEnv: call reset() before step()')
        expected = (self.num_envs, self.num_agents, 2)
        if tuple(getattr(actions, 'shape', ())) != expected:
            raise ValueError(f'{self.team.name.lower()} actions must have shape {expected} (games, agents, 2), got '
                             f'{tuple(getattr(actions, "shape", ()))}')
        restarting = self._pending
        joint = (actions, None) if self.team is Team.CAMERA else (None, actions)
        observations, team_rewards, terminated, truncated, info = self.vec.step_games(*joint, restart_ended=False)
        live = ~restarting
        rewards = self._rewards(team_rewards, info, live)     # (same_step: before the ended games restart)
        summed = rewards if rewards.dim() == 1 else rewards.sum(dim=1)
        zero = torch.zeros((), dtype=torch.float64, device=summed.device)
        self._sum += torch.where(live, summed.to(torch.float64), zero)
        ended = live & (terminated | truncated)
        target_return = torch.where(ended, info['episode_target_return'], zero)
        episode = {'r': torch.where(ended, self._sum, zero),
                   'l': torch.where(ended, info['episode_length'], torch.zeros_like(info['episode_length'])),
                   'coverage_rate': torch.where(ended, info['episode_coverage_rate'], zero),
                   'real_coverage_rate': torch.where(ended, info['episode_real_coverage_rate'], zero),
                   'transport_rate': torch.where(ended, info['transport_rate'], zero),
                   'camera_return': -target_return, 'target_return': target_return,
                   'normalized_target_return': target_return / self._max_reward,
                   'delivered_cargoes': torch.where(ended, info['delivered_cargoes'],
                                                    torch.zeros_like(info['delivered_cargoes']))}
        self._sum.masked_fill_(ended, 0.0)
        infos = {'coverage_rate': info['coverage_rate'], EPISODE_INFO: episode, f'_{EPISODE_INFO}': ended}
        if self.vec.next_step:
            self._pending = ended
        else:
            done = terminated | truncated
            if keep_final and bool(done.any()):          # before the ended games restart
                infos.update(final_obs=observations[self._own].clone(), _final_obs=done,
                             final_info=self.vec.final_info(done), _final_info=done)
            self.vec.restart_ended()
        return observations[self._own], rewards, terminated, truncated, infos

    def state_dict(self) -> dict:
        """The device env's state (`DeviceVecEnv.state_dict`) and the episodes' running sums and pending
        restarts, as host arrays: `load_state_dict` on an env made alike continues exactly."""
        return dict(vec=self.vec.state_dict(), sums=self._sum.cpu().numpy().copy(),
                    pending=self._pending.cpu().numpy().copy(), started=self._started)

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output."""
        import torch

        self.vec.load_state_dict(state['vec'])
        self._sum.copy_(torch.as_tensor(state['sums']))
        self._pending.copy_(torch.as_tensor(state['pending']))
        self._started = bool(state['started'])

    def state(self):
        """(B, S) tensor: every game's global state (`DeviceVecEnv.state`)."""
        return self.vec.state()

    def close(self, **kwargs) -> None:
        self.vec.close()

    def __repr__(self) -> str:
        return (f'DeviceTeamVecEnv({self.team.name.lower()}s of {self.config!r} on the device, '
                f'num_envs={self.num_envs}, reward={self.reward_kind!r})')
