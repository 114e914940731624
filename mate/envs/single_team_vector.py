"""`SingleTeamVecEnv`: B games of one team, the other team played inside by a batched team (greedy by default).

    import mate

    envs = mate.make_team_vec('MATE-4v8-9', team='camera', num_envs=64)           # the cameras vs greedy targets
    observations, infos = envs.reset(seed=0)                                       # (64, 4, D) float64
    for _ in range(1000):
        observations, rewards, terminations, truncations, infos = envs.step(envs.action_space.sample())
        if '_mate_episode' in infos:                                               # some games ended at this step
            print(infos['mate_episode']['coverage_rate'][infos['_mate_episode']])

What a researcher's own algorithm steps (CleanRL-style files, `examples/own_policy_ppo.py`), torch-free. It follows
Gymnasium's vector conventions (a `gymnasium.vector.VectorEnv`):

* **spaces**: one env of the vector env is one game of the whole team, so `single_observation_space` is
  Box(N, D), one row per agent (not Box(D)), and `observation_space` Box(B, N, D): the team's raw observations (the
  layouts of `mate.spaces`, in `observation_dtype`); `single_action_space` Box(N, 2) and `action_space`
  Box(B, N, 2), float64: cameras (rotation, zoom) in degrees, targets a displacement (dx, dy). The bounds are the
  largest any agent of the game has; the core clips each agent's action to its own step limits, as the two-team
  env does. Actions of another shape raise ValueError (nothing is reshaped). `AgentsAsEnvs` views the same games
  with one env per agent: Box(D) and Box(2).
* **rewards** (`reward`): 'team', the team's dense reward of the config, (B,) (camera reward = -target reward);
  'coverage' (cameras), the coverage rate of the step, (B,), the reward the paper trains cameras on; 'own'
  (targets), each target's own part of the team reward (its tracking penalty and deliveries; they sum to the
  team's), (B, N); 'difference' (cameras), each camera's marginal share of the coverage rate, (B, N).
* **autoreset**: Gymnasium 1.x's `next_step` by default (the step after game i ended ignores its actions, starts its
  next episode and returns reward 0, terminated = truncated = False), or `same_step` (`infos['final_obs']` holds
  the ended episodes' last observations); the opponent starts its episode where the game does.
* **infos**: a dict of (B,) arrays (`coverage_rate`, `real_coverage_rate`, `mean_transport_rate`,
  `num_delivered_cargoes`, `episode_step`, and the episode so far as the core counts it: `episode_coverage_rate`,
  `episode_real_coverage_rate`, `episode_target_return`); on a step where games end, `infos['mate_episode']` holds
  each ended game's statistics (zeros elsewhere) with the mask `infos['_mate_episode']`: `r` the summed reward of
  the chosen kind (summed over agents for per-agent rewards), `l` the length in env steps, `coverage_rate`,
  `real_coverage_rate` (means over the episode's steps), `transport_rate` (at its end), `camera_return` and
  `target_return` (the config's team rewards summed), `normalized_target_return` (the target return divided by the
  preset's largest one: the targets' benchmark metric), `delivered_cargoes`. The key is not Gymnasium's
  `episode`, which `gymnasium.wrappers.vector.RecordEpisodeStatistics` adds (`r`, `l`, `t`) and refuses to
  overwrite.

**Gymnasium's vector wrappers** (`gymnasium.wrappers.vector`) apply as to any `VectorEnv` (tested:
`RecordEpisodeStatistics`, `NormalizeObservation`, `NormalizeReward`, `ClipAction`, `RescaleAction`,
`TransformObservation`, `TransformReward`, `ClipReward`, `FlattenObservation`, `DtypeObservation`,
`DictInfoToList`), with the rewards (B,) of 'team' and 'coverage'. They assume one reward per env: the per-agent
kinds' (B, N) rewards go through `AgentsAsEnvs` first (one env per agent, so each agent's return is recorded and
normalised). `NormalizeObservation` takes `next_step` autoreset only (Gymnasium's own check), and its statistics
are per agent slot ((N, D)); `RecordEpisodeStatistics` counts as under `next_step` (with `same_step` its later
episodes miss their first step; `mate_episode` does not).

**Seeding**: `reset(seed=s)` seeds game i with s + i and the opponent's row i with s + i too, so game i is the
episode `mate evaluate --seed s` plays as its episode i (and `mate.score_policy`, the PettingZoo adapters and the
`MultiCamera`/`MultiTarget` wrappers with a greedy opponent play, for the same seed); `reset()` without a seed
continues every stream.

**Opponents** (`opponent`): a built-in agent name with a batched form ('greedy', 'random'; 'pretrained:NAME' and
'checkpoint:PATH' with the train extra), or a factory `f(num_envs, counts, seed)` of
any batched team of the `mate.teams` protocol (counts: (Nc, Nt, No)); a seeded reset builds it anew with that seed.

Differences from `gymnasium.vector.VectorEnv`: no `render`; `call`/`get_attr` are not provided (one process holds
all B games); per-agent rewards are (B, N).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import VectorEnv, VectorWrapper
from gymnasium.vector.utils import batch_space

from ..core.arrays import array_namespace, as_kind_of, copied, float64_copy, host_copy, is_host, maybe_any
from ..messages import Team
from ..evaluation.protocol import EPISODE_INFO, REWARDS, agent_team_factory, checked_reward, paper_config
from ..teams.interface import as_team
from .vector import AutoresetMode, make_vec
from .vector_contract import is_seed

__all__ = ['DEVICE_OPPONENTS', 'EPISODE_INFO', 'REWARDS', 'AgentsAsEnvs', 'SingleTeamVecEnv', 'make_team_vec',
           'opponent_factory', 'step_rewards']

EPISODE_KEYS = ('r', 'l', 'coverage_rate', 'real_coverage_rate', 'transport_rate', 'camera_return', 'target_return',
                'normalized_target_return', 'delivered_cargoes')
"""The statistics of `infos['mate_episode']`."""


DEVICE_OPPONENTS = ('greedy', 'random')
"""The built-in opponents with a team on a CUDA device (`mate.teams.device.DeviceRuleTeam`)."""
FINAL_KEYS = ('final_obs', '_final_obs', 'final_info', '_final_info')
"""Same-step autoreset's keys, which `step_games` passes on only with `keep_final`."""


def opponent_factory(opponent, team: Team, options: dict | None = None, device: str | None = None,
                     block: int | None = None):
    """A factory f(num_envs, counts, seed) of the team that plays against `team` (module docstring;
    `mate.evaluation.protocol.agent_team_factory`, but the upper-bound cameras, which read the true state of a whole
    batch, are no opponent). `options`: the built-in agent's options. `device` 'cuda': 'greedy' and 'random' as device
    teams (`DeviceRuleTeam`, `block` threads a block); a factory there must make a team that plays tensors."""
    other = Team.TARGET if team is Team.CAMERA else Team.CAMERA
    options = dict(options or {})
    if opponent == 'upper-bound':
        raise ValueError('the upper-bound cameras read the true state of a whole batch; they are a reference of '
                         'mate.score_policy, not an opponent of the single-team env')
    if callable(opponent) and not isinstance(opponent, str):
        if options:
            raise ValueError('opponent_options are the options of a built-in opponent; a factory takes its own')
        return opponent
    if device is not None:
        if opponent not in DEVICE_OPPONENTS:
            raise ValueError(f'on a device the opponent is one of {", ".join(DEVICE_OPPONENTS)} (or a factory of a '
                             f'team that plays tensors), got {opponent!r}')
        from ..core.device import BLOCK
        from ..teams.device import DeviceRuleTeam, device_team

        device_team(opponent, other, 1, (1, 1, 0), **options)     # bad options fail now, with the usual line
        return lambda num_envs, counts, seed: DeviceRuleTeam(opponent, other, num_envs, counts, seed=seed,
                                                             block=block or BLOCK, **options)
    if options:
        from ..teams import RULE_TEAMS, make_team

        if opponent not in RULE_TEAMS:
            raise ValueError(f'opponent_options are the options of a built-in opponent ({", ".join(RULE_TEAMS)}), '
                             f'not of {opponent!r}')
        make_team(opponent, other, 1, (1, 1, 0), **options)
        return lambda num_envs, counts, seed: make_team(opponent, other, num_envs, counts, seed=seed, **options)
    return agent_team_factory(opponent, other, 'opponent')


def step_rewards(reward: str, world, team_reward, coverage_rate):
    """The rewards of kind `reward` (`REWARDS`) of the step just played in the batched world (B, ...): 'team' the
    own team's reward (B,), 'coverage' the coverage rate (B,), 'difference' (B, Nc) and 'own' (B, Nt) per agent:
    each target's part of the team's dense reward as the core's step computed it (`World.target_reward_parts`: its
    tracking penalty and its delivery's pay; they sum to the team reward), and each camera's difference credit
    (`World.camera_reward_parts`: the share of the targets it alone tracks). Fresh arrays (tensors for a world of
    tensors), float64."""
    if reward == 'team':
        return float64_copy(team_reward)
    if reward == 'coverage':
        return float64_copy(coverage_rate)
    return copied(world.camera_reward_parts if reward == 'difference' else world.target_reward_parts)


class SingleTeamVecEnv(VectorEnv):
    """B games of one team against a batched opponent, as a Gymnasium `VectorEnv` (module docstring), on the CPU or
    on a CUDA device (`device='cuda'`: torch tensors on it in and out).

    One env is one game of the whole team of N agents: `single_observation_space` is Box(N, D) (a row per agent,
    D the team's observation length), `observation_space` Box(B, N, D), `single_action_space` Box(N, 2) and
    `action_space` Box(B, N, 2); rewards are (B,) ('team', 'coverage') or (B, N) ('own', 'difference'). For one env
    per agent (Box(D), Box(2), rewards (B * N,)), wrap it in `AgentsAsEnvs`.

    Args:
        config: a preset name, a YAML/JSON path or a dict (None: the paper's game of the team, MATE-4v8-9 for
            cameras, MATE-2v4-0 for targets).
        team: 'camera' or 'target', the team the caller plays.
        num_envs: B.
        opponent: the other team: an agent name or a factory f(num_envs, counts, seed) (on a device 'greedy' or
            'random', played there by `mate.teams.device.DeviceRuleTeam`).
        opponent_options: the built-in opponent's options (e.g. {'frame_skip': 4} for 'random').
        reward: 'team', 'coverage' (cameras), 'own' (targets) or 'difference' (cameras).
        max_episode_steps: the episodes' step cap (None: the config's).
        observation_dtype: np.float64 or np.float32.
        autoreset_mode: 'next_step' (default) or 'same_step'.
        device: None or 'cpu', or 'cuda' / 'cuda:N' (the gpu extra: `mate.make_vec(..., device='cuda')`).
        block: threads per CUDA block (device only).
        **overrides: config keys (deep-merged, as for `mate.make_vec`).
    """

    metadata = {'render_modes': [], 'autoreset_mode': AutoresetMode.NEXT_STEP}

    def __init__(self, config: Any = None, team='camera', num_envs: int = 1, *, opponent='greedy',
                 opponent_options: dict | None = None, reward: str = 'team', max_episode_steps: int | None = None,
                 observation_dtype=np.float64, autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 device: str | None = None, block: int | None = None, **overrides) -> None:
        self.team = as_team(team)
        name = self.team.name.lower()
        checked_reward(self.team, reward)
        if max_episode_steps is not None:
            if not isinstance(max_episode_steps, (int, np.integer)) or max_episode_steps < 1:
                raise ValueError(f'max_episode_steps must be a positive integer or None, got {max_episode_steps!r}')
            overrides['max_episode_steps'] = int(max_episode_steps)
        on_device = device is not None and str(device) != 'cpu'
        if on_device and block is not None:
            overrides['block'] = block
        elif block is not None:
            raise ValueError('block (threads per CUDA block) is a device option: pass device=\'cuda\' too')
        self.config = paper_config(self.team) if config is None else config
        self.reward_kind = reward
        self.vec = make_vec('MultiAgentTracking-v0', num_envs=num_envs, config=self.config,
                            observation_dtype=observation_dtype, autoreset_mode=autoreset_mode,
                            device=device if on_device else None, **overrides)
        if self.vec.autoreset_mode is AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode must be 'next_step' or 'same_step' (play_batch plays without autoreset)")
        self.metadata = {'render_modes': [], 'autoreset_mode': self.vec.autoreset_mode}
        self.render_mode = None
        self.num_envs = self.vec.num_envs
        self.counts = (self.vec.num_cameras, self.vec.num_targets, self.vec.num_obstacles)
        self.num_agents = self.counts[0] if self.team is Team.CAMERA else self.counts[1]
        if self.num_agents < 1:
            raise ValueError(f'the game has no {name}s to play')
        self._own = 0 if self.team is Team.CAMERA else 1
        self.single_observation_space = self.vec.single_observation_space[self._own]
        self.observation_space = self.vec.observation_space[self._own]
        joint = self.vec.single_action_space[self._own]
        self.single_action_space = spaces.Box(joint.low, joint.high, dtype=np.float64)
        self.action_space = spaces.Box(np.broadcast_to(joint.low, (self.num_envs, *joint.shape)),
                                       np.broadcast_to(joint.high, (self.num_envs, *joint.shape)), dtype=np.float64)
        self._make_opponent = opponent_factory(opponent, self.team, opponent_options, device if on_device else None,
                                               block)
        self.opponent = self._make_opponent(self.num_envs, self.counts, None)
        self._max_reward = float(self.vec.params.max_target_team_episode_reward)
        like = self.vec.world.target_reward          # an array of the games' kind, on their device
        self._host = is_host(like)
        self._sums = {'r': as_kind_of(np.zeros(self.num_envs), like)}  # the learner's reward (the game's: the core's)
        self._other_obs = None
        self._pending = as_kind_of(np.zeros(self.num_envs, dtype=bool), like)   # next_step: rows restarting next
        self._every = as_kind_of(np.ones(self.num_envs, dtype=bool), like)
        self._no_episode = None        # step_games' mate_episode of a step where no game ended (the host: made once)

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | None = None, options: dict | None = None, opponent_seed: int | None = None):
        """Start new episodes in every game; returns (observations (B, N, D), infos). `seed` s: game i and the
        opponent's row i are seeded s + i (`opponent_seed` o: the opponent's row i with o + i); None continues
        their streams."""
        if opponent_seed is not None and seed is None:
            raise ValueError('opponent_seed needs an int seed (an unseeded reset goes on with every stream)')
        for label, value in (('seed', seed), ('opponent_seed', opponent_seed)):
            if value is not None and not is_seed(value):
                raise ValueError(f'{label} must be a non-negative integer or None, got {value!r}')
        if seed is not None:
            self.opponent = self._make_opponent(self.num_envs, self.counts,
                                                int(seed if opponent_seed is None else opponent_seed))
        observations, infos = self.vec.reset(seed=seed, options=options)
        self._other_obs = observations[1 - self._own]
        self.opponent.reset(self._other_obs, self._every)
        for values in self._sums.values():
            values[...] = 0.0
        self._pending[...] = False
        return observations[self._own], infos

    def restart(self, mask) -> None:
        """The games of `mask` (B,) bool (host) start their next episode now, their streams going on, none of them
        waiting for a next_step restart any more (what a partial reset of TorchRL asks for)."""
        mask = np.asarray(mask, bool)
        observations, _ = self.vec.reset(options={'reset_mask': mask})
        self._other_obs = observations[1 - self._own]
        restarted = as_kind_of(mask, self._pending)
        self.opponent.reset(self._other_obs, restarted)
        self._pending = self._pending & ~restarted
        self._sums['r'] = array_namespace(restarted).where(restarted, 0.0, self._sums['r'])

    def _joint(self, actions) -> tuple:
        other = self.opponent.act(self._other_obs)
        return (actions, other) if self.team is Team.CAMERA else (other, actions)

    def _checked(self, actions):
        if not hasattr(actions, 'shape'):
            actions = np.asarray(actions)
        expected = (self.num_envs, self.num_agents, 2)
        if tuple(actions.shape) != expected:
            raise ValueError(f'{self.team.name.lower()} actions must have shape {expected} (games, agents, 2), got '
                             f'{tuple(actions.shape)}')
        return actions

    def step(self, actions):
        """One env step of every game with the team's `actions` (B, N, 2); returns (observations, rewards,
        terminations, truncations, infos) (module docstring)."""
        return self._step(actions, games_only=False)

    def step_games(self, actions, keep_final: bool = False):
        """`step` as the training envs of `mate.learn` call it on either device: on a device without the refusal
        of NaN and inf, reading nothing back under next_step autoreset; `mate_episode` and its mask `_mate_episode`
        at every step (zeros and False where no game ended: on the host read-only arrays, the same every time);
        `final_obs` / `final_info` (same_step) only with `keep_final`."""
        return self._step(actions, games_only=True, keep_final=keep_final)

    def _step(self, actions, games_only: bool, keep_final: bool = False):
        if self._other_obs is None:
            raise RuntimeError('SingleTeamVecEnv: call reset() before step()')
        actions = self._checked(actions)
        restarting = self._pending
        joint = self._joint(actions)
        step = self.vec.step_games if games_only else self.vec.step
        observations, team_rewards, terminations, truncations, infos = step(joint)
        self._other_obs = observations[1 - self._own]
        xp = array_namespace(terminations)
        rewards = step_rewards(self.reward_kind, self.vec.world, team_rewards[self._own], infos['coverage_rate'])
        live = ~restarting               # a game restarting at this step (next_step) is rewarded 0, whatever the kind
        rewards = xp.where(live if rewards.ndim == 1 else live[:, None], rewards, 0.0)
        if 'final_info' in infos:          # same_step: the ended games were reset; their step is in final_info
            rewards = self._final_rewards(rewards, infos['final_info'], infos['_final_info'])
        ended = live & (terminations | truncations)
        self._sums['r'] = self._sums['r'] + xp.where(live, rewards if rewards.ndim == 1 else xp.sum(rewards, axis=1),
                                                     0.0)
        if maybe_any(ended):              # (a tensor: always, reading nothing back)
            episode = self._episode_statistics(ended, infos)
            if games_only or bool(xp.any(ended)):
                infos[EPISODE_INFO], infos[f'_{EPISODE_INFO}'] = episode, ended
        elif games_only:
            infos[EPISODE_INFO], infos[f'_{EPISODE_INFO}'] = self._no_episode_statistics(infos)
        if self.vec.autoreset_mode is AutoresetMode.NEXT_STEP:
            if maybe_any(restarting):
                self.opponent.reset(self._other_obs, restarting)
            self._pending = ended
        elif maybe_any(ended):            # same_step: the ended games already show their next episode
            self.opponent.reset(self._other_obs, ended)
        if games_only and not keep_final:
            for key in FINAL_KEYS:
                infos.pop(key, None)
        elif 'final_obs' in infos:
            infos['final_obs'] = self._own_final_obs(infos['final_obs'])
        return observations[self._own], rewards, terminations, truncations, infos

    def _own_final_obs(self, final_obs):
        """Same-step autoreset's last observations of the ended games, of the own team: on the host (B,) objects,
        the (N, D) arrays of the ended games and None elsewhere; on a device one (B, N, D) tensor, valid where
        `_final_obs` (the vector env's forms)."""
        if not self._host:
            return final_obs[self._own]
        final = np.full(self.num_envs, None, dtype=object)
        for game, pair in enumerate(final_obs):
            if pair is not None:
                final[game] = pair[self._own]
        return final

    def _no_episode_statistics(self, infos) -> tuple[dict, np.ndarray]:
        """`step_games`' mate_episode and mask of a host step where no game ended: read-only zeros, made once."""
        if self._no_episode is None:
            nothing = np.zeros(self.num_envs, dtype=bool)
            self._no_episode = (self._episode_statistics(nothing, infos), nothing)
            for array in (*self._no_episode[0].values(), nothing):
                array.setflags(write=False)
        return self._no_episode

    def _final_rewards(self, rewards, final: dict, done):
        """`rewards` with those of the games that ended in a same_step autoreset taken from their ended step (the
        world and the infos show their next episode already)."""
        xp = array_namespace(done)
        if self.reward_kind == 'coverage':
            return xp.where(done, final['coverage_rate'], rewards)
        if self.reward_kind in ('own', 'difference'):
            parts = final['target_reward_parts' if self.reward_kind == 'own' else 'camera_reward_parts']
            return xp.where(done[:, None], parts, rewards)
        return rewards

    def _episode_statistics(self, ended, infos) -> dict:
        """`infos['mate_episode']` of the games that ended at this step (zeros elsewhere): the learner's summed
        reward, and the game's own statistics as the core counted them (`mate.core.world.episode_statistics`; with
        same_step autoreset, from `final_info`, the ended games' last step before their reset)."""
        xp = array_namespace(ended)
        game = infos.get('final_info', infos)
        target_return = xp.where(ended, game['episode_target_return'], 0.0)
        zero = xp.zeros_like(game['episode_step'])
        stats = {'r': xp.where(ended, self._sums['r'], 0.0),
                 'l': xp.astype(xp.where(ended, game['episode_step'], zero), xp.int64),
                 'camera_return': xp.where(ended, -game['episode_target_return'], 0.0), 'target_return': target_return,
                 'normalized_target_return': target_return / self._max_reward,
                 'transport_rate': xp.where(ended, game['mean_transport_rate'], 0.0),
                 'delivered_cargoes': xp.astype(xp.where(ended, game['num_delivered_cargoes'],
                                                         xp.zeros_like(game['num_delivered_cargoes'])), xp.int64)}
        for key in ('coverage_rate', 'real_coverage_rate'):
            stats[key] = xp.where(ended, game[f'episode_{key}'], 0.0)
        self._sums['r'] = xp.where(ended, 0.0, self._sums['r'])
        return {key: stats[key] for key in EPISODE_KEYS}

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict:
        """Everything the games' future depends on, as plain data (host arrays on either device): the vector env's
        state (worlds and random streams), the opponent's (`state_dict()` of the `mate.teams` teams, the device
        teams and trained policies), the episodes' running sums and the rows waiting for their autoreset.
        `load_state_dict` on an env made alike continues exactly."""
        if not hasattr(self.opponent, 'state_dict'):
            raise TypeError(f'the opponent {type(self.opponent).__name__} has no state_dict(): its state cannot be '
                            'saved')
        return dict(vec=self.vec.state_dict(), opponent=self.opponent.state_dict(), pending=host_copy(self._pending),
                    sums={key: host_copy(values) for key, values in self._sums.items()})

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from an env of the same game, size and opponent kind;
        `pending` and `sums` may be left out: none pending, zero sums)."""
        self.vec.load_state_dict(state['vec'])
        self.opponent.load_state_dict(state['opponent'])
        self._other_obs = self.vec.observations[1 - self._own]
        like = self._pending
        self._pending = as_kind_of(np.broadcast_to(np.asarray(state.get('pending', False)), (self.num_envs,)).copy(),
                                   like)
        sums = state.get('sums', {})
        self._sums['r'] = as_kind_of(np.broadcast_to(np.asarray(sums.get('r', 0.0), np.float64),
                                                     (self.num_envs,)).copy(), like)
        for key in ('coverage_rate', 'real_coverage_rate'):   # a state of an earlier version kept these sums here
            if f'{key}_sum' not in state['vec']['world'] and key in sums:
                getattr(self.vec.world, f'{key}_sum')[...] = sums[key]

    # ------------------------------------------------------------------ extras
    def state(self):
        """(B, S) the global state of every game (`mate.make_vec`'s `state()`), e.g. for a centralised critic."""
        return self.vec.state()

    @property
    def single_state_space(self) -> spaces.Box:
        return self.vec.single_state_space

    def close(self, **kwargs) -> None:
        if hasattr(self, 'vec'):          # not when the constructor refused its arguments
            self.vec.close()

    def __repr__(self) -> str:
        where = '' if self._host else ' on the device'
        return (f'SingleTeamVecEnv({self.team.name.lower()}s of {self.config!r} vs {type(self.opponent).__name__}'
                f'{where}, num_envs={self.num_envs}, reward={self.reward_kind!r})')


class AgentsAsEnvs(VectorWrapper):
    """The single-team env seen one agent at a time: B games of N agents as a `VectorEnv` of B * N envs.

    Env k = b * N + n is agent n of game b. What single-agent learners and Gymnasium's vector wrappers expect, the
    per-agent reward kinds included (independent learners with parameter sharing, CleanRL's PPO files unchanged):

    * **spaces**: `single_observation_space` Box(D) and `observation_space` Box(B * N, D), in the env's dtype;
      `single_action_space` Box(2), float64, `action_space` Box(B * N, 2) (the bounds of the team env: the largest
      any agent has).
    * **step** takes actions (B * N, 2) (any other shape: ValueError) and returns observations (B * N, D) (a view of
      the team env's buffer, overwritten by the next step), rewards (B * N,) float64 (each agent's own for 'own' and
      'difference', the game's reward repeated to its N agents for 'team' and 'coverage'), terminations and
      truncations (B * N,) (a game's agents end together).
    * **infos**: every array of the team env's infos with one row per game repeated to its agents
      (`np.repeat(value, N, axis=0)`, nested dicts such as `mate_episode` and `final_info` too), so the masks
      `_key` are (B * N,); `final_obs` (same_step) holds each agent's last observation (D,).
    * **reset(seed=s)** seeds game b with s + b (its agents share their game); partial resets (`reset_mask`) are
      refused: a game restarts with all its agents. `state()`: (B * N, S), the global state of each agent's game.

    Gymnasium's `RecordEpisodeStatistics` then records each agent's return (`r`) and the game's length (`l`),
    `NormalizeReward` normalises each agent's discounted return, `NormalizeObservation` pools its statistics over
    the agents (D values).

    Args:
        env: a `SingleTeamVecEnv` (`mate.make_team_vec(...)`), or a Gymnasium wrapper of one whose spaces are still
            Box(B, N, D) and Box(B, N, 2).
    """

    def __init__(self, env: VectorEnv) -> None:
        super().__init__(env)
        observations, actions = env.observation_space, env.action_space
        if not (isinstance(observations, spaces.Box) and isinstance(actions, spaces.Box) and
                len(observations.shape) == 3 and actions.shape == (*observations.shape[:2], 2)):
            raise ValueError('AgentsAsEnvs needs a single-team env (mate.make_team_vec) with observations '
                             f'Box(B, N, D) and actions Box(B, N, 2), got {observations} and {actions}')
        self.num_games, self.num_agents = observations.shape[:2]
        self._num_envs = self.num_games * self.num_agents
        low, high = observations.low.min(axis=(0, 1)), observations.high.max(axis=(0, 1))
        self.single_observation_space = spaces.Box(low, high, dtype=observations.dtype)
        self.single_action_space = spaces.Box(actions.low.min(axis=(0, 1)), actions.high.max(axis=(0, 1)),
                                              dtype=actions.dtype)
        self.observation_space = batch_space(self.single_observation_space, self._num_envs)
        self.action_space = batch_space(self.single_action_space, self._num_envs)

    @property
    def num_envs(self) -> int:
        """B * N: one env per agent."""
        return self._num_envs

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start new episodes in every game; returns (observations (B * N, D), infos with (B * N,) rows)."""
        if options and 'reset_mask' in options:
            raise ValueError('AgentsAsEnvs resets whole games: call reset() without a reset_mask (the games '
                             'autoreset, next_step or same_step)')
        observations, infos = self.env.reset(seed=seed, options=options)
        return self._rows(observations), self._per_agent(infos)

    def step(self, actions):
        """One env step of every game with the agents' `actions` (B * N, 2); returns (observations (B * N, D),
        rewards (B * N,), terminations (B * N,), truncations (B * N,), infos) (class docstring)."""
        actions = np.asarray(actions)
        if actions.shape != self.action_space.shape:
            raise ValueError(f'actions must have shape {self.action_space.shape} (one row per agent: games x agents '
                             f'= {self.num_games} x {self.num_agents}, 2), got {actions.shape}')
        observations, rewards, terminations, truncations, infos = self.env.step(
            actions.reshape(self.num_games, self.num_agents, 2))
        rewards = np.asarray(rewards, dtype=np.float64)
        rewards = (rewards.reshape(self._num_envs) if rewards.ndim == 2
                   else np.repeat(rewards, self.num_agents))
        return (self._rows(observations), rewards, np.repeat(terminations, self.num_agents),
                np.repeat(truncations, self.num_agents), self._per_agent(infos))

    def state(self) -> np.ndarray:
        """(B * N, S): the global state of each agent's game (`SingleTeamVecEnv.state`, repeated to its agents)."""
        return np.repeat(self.env.unwrapped.state(), self.num_agents, axis=0)

    def _rows(self, observations: np.ndarray) -> np.ndarray:
        return observations.reshape(self._num_envs, *observations.shape[2:])

    def _per_agent(self, infos: dict) -> dict:
        """`infos` with every per-game array repeated to the game's agents (nested dicts too)."""
        out = {}
        for key, value in infos.items():
            if isinstance(value, dict):
                out[key] = self._per_agent(value)
            elif key == 'final_obs':        # (B,) objects: the ended games' (N, D) last observations, else None
                rows = np.full(self._num_envs, None, dtype=object)
                for game in np.flatnonzero([last is not None for last in value]):
                    for agent in range(self.num_agents):
                        rows[game * self.num_agents + agent] = value[game][agent]
                out[key] = rows
            elif isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == self.num_games:
                out[key] = np.repeat(value, self.num_agents, axis=0)
            else:
                out[key] = value
        return out

    def __repr__(self) -> str:
        return f'AgentsAsEnvs({self.env!r}: {self.num_games} games x {self.num_agents} agents)'


def make_team_vec(config: Any = None, team='camera', num_envs: int = 1, *, device: str | None = None, **kwargs):
    """`SingleTeamVecEnv(config, team, num_envs, device=device, **kwargs)`: B games of `team` against a batched
    opponent; `device='cuda'` (the gpu extra): the games and the opponent on a CUDA device, torch tensors in and out
    (opponents 'greedy' or 'random')."""
    return SingleTeamVecEnv(config, team, num_envs, device=device, **kwargs)   # (make_vec refuses another device)
