"""TorchRL: one team's batch of MATE games as a TorchRL `EnvBase` (the torchrl extra: `pip install -e '.[torchrl]'`).

    from mate.integrations.torchrl import MateTorchRLEnv
    from torchrl.envs.utils import check_env_specs

    env = MateTorchRLEnv('MATE-4v8-9', team='camera', num_envs=64)   # the cameras vs the greedy targets
    check_env_specs(env)
    rollout = env.rollout(100)                    # random actions: a TensorDict of batch size (64, 100)
    rollout['camera', 'observation'].shape        # (64, 100, 4, D)

Over `mate.make_team_vec` (`SingleTeamVecEnv`: B games of the trained team, the other played inside by a batched
team, the greedy rules by default), in TorchRL's multi-agent layout (as VMAS and PettingZoo's wrappers use it): the
team is a group named after it, with `(team, 'observation')` (B, N, D), `(team, 'action')` (B, N, 2) bounded by
the action box, `(team, 'reward')` (B, N, 1) (the team reward repeated to every agent, or each agent's own for the
'own' and 'difference' rewards), and `done`, `terminated`, `truncated` (B, 1) at the root. A game that ends shows
its last observation with done; TorchRL's partial reset (`_reset` mask) then hands out the next episode's first
observation, which the batch had already started (same-step autoreset). `set_seed(s)` seeds game i with s + i at
the next full reset, as `make_team_vec` does. Tensors live on `device`; the games run on the CPU (the numba core)
or, with `game_device='cuda'`, on the GPU (`mate.make_team_vec(..., device='cuda')`): there the ended games wait
(next_step autoreset) until the partial reset restarts them, which plays the same games without a host round trip.

BenchMARL builds its tasks on TorchRL environments; its releases pin torchrl below 0.12, this adapter is tested
with the torchrl that installs beside this package's torch (docs/ecosystem notes in docs/training.md).
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from ..envs.single_team_vector import make_team_vec

__all__ = ['MateTorchRLEnv']


class MateTorchRLEnv(EnvBase):
    """B games of one team of MATE as a TorchRL environment (module docstring).

    Args:
        config: a preset name, a config file or dict (`mate.make_team_vec`).
        team: 'camera' or 'target', the team the actions drive; also the group's key.
        num_envs: B, the games stepped at once.
        device: where the tensors are returned ('cpu', 'cuda', ...).
        game_device: None or 'cpu' (the games on the CPU, the numba core), or 'cuda': the games and the opponent on
            the GPU (`mate.make_team_vec(..., device='cuda')`, the gpu extra; opponents 'greedy' or 'random').
        **kwargs: more `mate.make_team_vec` options: `reward`, `opponent`, `max_episode_steps`, ...
    """

    def __init__(self, config=None, team: str = 'camera', num_envs: int = 64, device='cpu', game_device=None,
                 **kwargs):
        if 'autoreset_mode' in kwargs:
            raise ValueError('MateTorchRLEnv sets autoreset_mode itself (TorchRL resets finished games with _reset)')
        self.on_device = game_device is not None and str(game_device) != 'cpu'
        # on a device the ended games wait (next_step) until TorchRL's partial reset restarts them
        self.envs = make_team_vec(config, team=team, num_envs=num_envs, observation_dtype=np.float32,
                                  autoreset_mode='next_step' if self.on_device else 'same_step', device=game_device,
                                  **kwargs)
        super().__init__(batch_size=torch.Size([num_envs]), device=device)
        self.group = team
        B, (N, D) = num_envs, self.envs.single_observation_space.shape
        box = self.envs.single_action_space
        agents = torch.Size([B, N])
        self.observation_spec = Composite(
            {team: Composite(observation=Unbounded(shape=(B, N, D), dtype=torch.float32, device=self.device),
                             shape=agents)}, shape=self.batch_size, device=self.device)
        low = torch.as_tensor(np.broadcast_to(box.low, (B, N, 2)).copy(), dtype=torch.float32)
        high = torch.as_tensor(np.broadcast_to(box.high, (B, N, 2)).copy(), dtype=torch.float32)
        self.action_spec = Composite(
            {team: Composite(action=Bounded(low=low, high=high, shape=(B, N, 2), dtype=torch.float32,
                                            device=self.device), shape=agents)},
            shape=self.batch_size, device=self.device)
        self.reward_spec = Composite(
            {team: Composite(reward=Unbounded(shape=(B, N, 1), dtype=torch.float32, device=self.device),
                             shape=agents)}, shape=self.batch_size, device=self.device)
        flag = Categorical(2, shape=(B, 1), dtype=torch.bool, device=self.device)
        self.done_spec = Composite(done=flag, terminated=flag.clone(), truncated=flag.clone(), shape=self.batch_size,
                                   device=self.device)
        self._seed: int | None = None
        self._current: np.ndarray | None = None     # (B, N, D) the games' observations now (new episodes included)

    def _set_seed(self, seed: int | None) -> None:
        self._seed = seed

    def _own(self, values, dtype) -> torch.Tensor:
        """`values` (a numpy array or a tensor, possibly the env's buffer) as a tensor of its own on `self.device`."""
        if isinstance(values, torch.Tensor):
            return values.to(self.device, dtype, copy=True)
        return torch.tensor(np.asarray(values), dtype=dtype, device=self.device)

    def _output(self, observation, rewards=None, terminated=None, truncated=None) -> TensorDictBase:
        """The TensorDict of a reset (no rewards, no flags set) or of a step, every tensor its own (the env's
        buffers are overwritten at its next step): `rewards` (B,) repeated to every agent, or (B, N)."""
        observation = self._own(observation, torch.float32)
        N = observation.shape[1]
        group = {'observation': observation}
        if rewards is None:
            terminated, truncated = (torch.zeros(self.batch_size, dtype=torch.bool, device=self.device)
                                     for _ in range(2))
        else:
            rewards = self._own(rewards, torch.float32)
            group['reward'] = (rewards[:, None].expand(-1, N) if rewards.dim() == 1 else rewards)[..., None].clone()
            terminated, truncated = self._own(terminated, torch.bool), self._own(truncated, torch.bool)
        return TensorDict({self.group: TensorDict(group, batch_size=self.batch_size + torch.Size([N])),
                           'done': (terminated | truncated)[:, None], 'terminated': terminated[:, None],
                           'truncated': truncated[:, None]}, batch_size=self.batch_size, device=self.device)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        partial = tensordict is not None and '_reset' in tensordict.keys() and self._current is not None
        if not partial:
            seed, self._seed = self._seed, None
            self._current, _ = self.envs.reset(seed=seed)
        elif self.on_device:            # the ended games waited (next_step): restart them now, streams going on
            self.envs.restart(tensordict.get('_reset').reshape(-1).cpu().numpy())
        return self._output(self._current)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = tensordict.get((self.group, 'action')).detach()
        if self.on_device:          # next_step autoreset: an ended game shows its last observation as it is
            observations, rewards, terminated, truncated, _ = self.envs.step_games(actions.to(torch.float64))
            return self._output(observations, rewards, terminated, truncated)
        observations, rewards, terminated, truncated, infos = self.envs.step(actions.to('cpu', torch.float64).numpy())
        self._current = observations
        shown = observations
        ended = terminated | truncated
        if ended.any():                               # the ended games show their last observation
            shown = observations.copy()
            for i in np.flatnonzero(ended):
                shown[i] = infos['final_obs'][i]
        return self._output(shown, rewards, terminated, truncated)
