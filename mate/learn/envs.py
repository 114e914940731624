"""The training view of B games for one team: `TeamEnvConfig` (the options every trainer takes) -> `TrainingEnv`.

A `TrainingEnv` steps the public single-team env, `mate.SingleTeamVecEnv` (the games and the opponent, which a
researcher's own algorithm steps too), and adds what mate's learners need on top: the policy spec's features and
action decoding, frame skip, the team's reward kinds and episode sums in decisions.

What a learner sees per decision (the paper's wrapper stack, done on arrays):

* observations through its `PolicySpec`'s `features` (relative coordinates rescaled to [-1, 1], the team's
  sighting-memory and target-velocity columns when the spec has them), and the global state rescaled with the
  state-space bounds, its unbounded counters log-compressed (`compress`);
* its held decision turned into env actions by the spec's `decode`: a grid move scaled by the agent's own step
  limits, the HRL executor re-aiming at the selected targets at every env step, or continuous shares;
* the opponent (by default the greedy rules, `mate.teams.GreedyTeam`) acting at every env step;
* frame skip k: a decision is held for k env steps; rewards are summed (camera: the coverage rate, the
  `AuxiliaryCameraRewards` setting of the paper; target: the raw dense team reward);
* episodes cut at `horizon` env steps (the paper: 500 decisions);
* `full_observability`: the trained team's raw observations go through `enhance_observations` (the
  `EnhancedObservation` wrapper's arrays: every entity seen, targets know which warehouses are empty), the
  paper's Fig. 6 ablation; the opponent keeps its partial view;
* `credit='difference'` (cameras): each camera is rewarded with its own marginal contribution to the coverage
  rate (the core's `World.camera_reward_parts`) instead of the team's; rewards are then (B, N);
* `credit='own'` (targets): each target is rewarded with its own part of the team's raw reward (the core's
  `World.target_reward_parts`: its tracking penalty and its deliveries), which sum to the team reward; rewards are
  then (B, N);
* `camera_reward='mixed'` (cameras): the population players' reward (docs/population.md), per env step
  0.5 coverage rate + 0.5 real coverage rate + 0.1 x the raw camera-team reward;
* `opponent=factory`: the other team is `factory(num_envs, counts, seed)`, any batched team of `mate.teams`
  (e.g. a mixture over a population, `mate psro`).

Episode ends inside a decision: the vector env runs in `next_step` autoreset mode, so a row that ends at env
step j restarts at step j + 1 and plays the rest of the held decision in its new episode; those steps' rewards
are credited to no one. The row's last observation and state are kept (`final_obs`, `final_state`) so that the
learner can bootstrap through a truncation.

`state_dict()` / `load_state_dict()` hold everything the batch's future depends on (the games, the opponent's
state and random streams, the sighting memory, the episode sums), for exact resumes.

On a GPU (`device='cuda'`, `mate train ... --game-device cuda`) the same class plays the games there: the
single-team env of that device (`mate.make_team_vec(..., device='cuda')`: the games and the greedy opponent as CUDA
kernels) and the same code over torch tensors (the spec's pipeline, the memory, `compress` and
`enhance_observations` serve both kinds, `mate.core.arrays`; the HRL executor runs as a kernel there). Only the
decision's episode records come to the host. What it does not play there is named by `device_unsupported`: the
population players' 'mixed' camera reward and opponents other than the greedy rules. The device teams draw from
counter-based streams of their own, so a run there and a CPU run (whose greedy team draws as the Python agents)
play other games of the same distribution (docs/performance.md, "The game on a CUDA device"); with the device
team's host twin (`mate.teams.device.HostTeam`) as the CPU env's opponent they play the same games.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Literal

import numpy as np

from ..agents.utils import box_scaling, scale_in_place
from ..core.arrays import array_namespace, as_kind_of, copied, float64_copy, host_array, host_copy, maybe_any
from ..constants import CAMERA_STATE_DIM_PRIVATE, PRESERVED_DIM, TARGET_STATE_DIM_PRIVATE
from ..messages import Team
from ..cli.options import option
from ..evaluation.protocol import EPISODE_INFO, PAPER_SETTINGS
from ..envs.registration import resolve_config
from ..envs.single_team_vector import make_team_vec
from ..teams import GreedyTeam
from ..core.observability import empty_warehouses, enhance_observations
from ..policies.memory import SightingMemory
from ..policies.spec import PolicySpec, as_team

__all__ = ['CAMERA_REWARDS', 'CREDITS', 'GAME_DEVICES', 'GameDeviceConfig', 'OPPONENT_SEED_OFFSET', 'PAPER_SETTINGS',
           'TeamEnvConfig', 'TeamVecEnv', 'TrainingEnv',
           'compress', 'device_game_available', 'device_unsupported', 'game_of', 'mixed_camera_reward',
           'team_positions']

CREDITS = ('team', 'difference', 'own')
"""How an agent's reward is assigned: the team's (both teams); a camera's own marginal contribution to the coverage
rate ('difference'); a target's own part of the team's raw reward ('own')."""
CAMERA_REWARDS = ('coverage', 'mixed')
"""What a camera team is rewarded with per env step: the coverage rate (the paper's cooperative runs), or
0.5 coverage + 0.5 real coverage + 0.1 raw camera-team reward (its population players, docs/population.md)."""


def game_of(config: str | None, team: str) -> tuple[str, str | None]:
    """(env_id, config path) of a `--config` value: a registered preset name (with or without '-v0'), a YAML/JSON
    path, or None for the paper preset of `team`. A bad name or file raises `ConfigError` listing the presets."""
    if config is None:
        return PAPER_SETTINGS[team]['env_id'], None
    from ..config import read_config
    from ..envs.registration import registered_ids

    name = str(config).removesuffix('-v0')
    if f'{name}-v0' in registered_ids():
        return f'{name}-v0', None
    read_config(config)
    return 'MultiAgentTracking-v0', str(config)


@dataclasses.dataclass
class TeamEnvConfig:
    """The game a team trains in and what its policy sees: options every trainer takes."""

    team: Literal['camera', 'target'] = option('camera', 'the team to train; the other team plays the greedy rules')
    config: str | None = option(None, "preset name (e.g. MATE-4v8-9) or YAML/JSON path; None: the paper's preset of "
                                      'the team (cameras MATE-4v8-9, targets MATE-2v4-0)', metavar='PRESET')
    frame_skip: int | None = option(None, 'env steps a decision is held; None: 5 for cameras, 10 for targets',
                                    minimum=1)
    horizon: int | None = option(None, 'env steps per training episode; None: 500 decisions', minimum=1)
    num_envs: int = option(64, 'games played at once', minimum=1)
    hrl: bool = option(False, 'cameras: the policy selects targets (one keep/ignore bit per target slot) and a rule '
                              'executor aims at them (paper §HRL)')
    memory: int = option(0, "cameras: env steps the team's shared memory of target sightings keeps a target, "
                            "appended to each camera's observation (the greedy cameras' 25); 0: none", minimum=0)
    velocity: bool = option(False, "cameras: append each seen target's displacement over one held decision")
    full_observability: bool = option(False, "the trained team sees every entity (EnhancedObservation, the paper's "
                                              'Fig. 6); evaluate with mate evaluate --enhanced-observation TEAM')
    credit: Literal['team', 'difference', 'own'] = option(
        'team', "reward every agent with the team's reward, or each with its own part: cameras their marginal share of "
                "the coverage ('difference'), targets their own tracking penalty and deliveries ('own')")
    seed: int = option(0, 'seed of the run: networks, envs, opponents, sampling', minimum=0)

    def __post_init__(self) -> None:
        camera_only = [flag for flag, used in (('--hrl', self.hrl), ('--memory', self.memory),
                                               ('--velocity', self.velocity),
                                               ("--credit difference", self.credit == 'difference')) if used]
        if camera_only and self.team != 'camera':
            raise ValueError(f'{camera_only[0]} exists for cameras only (--team camera)')
        if self.credit == 'own' and self.team != 'target':
            raise ValueError('--credit own (each target\'s own part of the team reward) exists for targets only '
                             '(--team target)')

    @property
    def env_id(self) -> str:
        return game_of(self.config, self.team)[0]

    @property
    def resolved_frame_skip(self) -> int:
        return int(self.frame_skip or PAPER_SETTINGS[self.team]['frame_skip'])

    @property
    def resolved_horizon(self) -> int:
        return int(self.horizon or 500 * self.resolved_frame_skip)

    def policy_spec(self, *, action: str = 'grid', envs=None, levels: int = 5, **network) -> PolicySpec:
        """The spec of the policy trained in this game: the action kind and the `network` keys of the trainer
        (`network`, `hidden`, `activation`, `lstm`, `algo`, `deterministic`: `PolicySpec`'s fields); with `envs`
        given, their `spec` with these network keys (PSRO's envs, the tests' toy tasks say what the policy sees)."""
        if envs is not None:
            return envs.spec.replace(**network)
        env_id, config = game_of(self.config, self.team)
        return PolicySpec.for_game(self.team, env_id, config, frame_skip=self.resolved_frame_skip, action=action,
                                   levels=levels, memory=self.memory, velocity=self.velocity,
                                   full_observability=self.full_observability, **network)

    def make_env(self, spec: PolicySpec, opponent=None, camera_reward: str = 'coverage',
                 device: str | None = None) -> TrainingEnv:
        """The training envs of this config for a policy of `spec` (the one place a `TrainingEnv` is made), with the
        games on `device` (None: the CPU)."""
        return TrainingEnv(spec, num_envs=self.num_envs, horizon=self.resolved_horizon, seed=self.seed,
                          credit=self.credit, camera_reward=camera_reward, opponent=opponent, device=device)


GAME_DEVICES = ('auto', 'cpu', 'cuda')
"""Where a trainer's games run (`--game-device`)."""


@dataclasses.dataclass
class GameDeviceConfig:
    """`--game-device`, an option of the trainers that train in a `TrainingEnv` (PPO's family, IQL, QMIX, MA-TD3):
    where the games and the greedy opponent run, and the training envs made there (`make_env`)."""

    game_device: Literal['auto', 'cpu', 'cuda'] = option(
        'auto', 'where the games and the greedy opponent run: cuda (CUDA kernels, the gpu extra), cpu (numba), or '
                'auto: on the GPU when --device is one and the settings allow it (not PSRO\'s mixed rewards and '
                'population opponents), else the CPU')

    def __post_init__(self) -> None:
        if self.game_device not in GAME_DEVICES:
            raise ValueError(f"--game-device must be auto, cpu or cuda, got {self.game_device!r}")

    def resolved_game_device(self, spec, opponent=None, camera_reward: str = 'coverage') -> str:
        """'cuda' or 'cpu': where `make_env` plays the games of `spec` (`game_device`). ValueError (one line) when
        cuda is asked for and a setting is not played on the device or numba sees no CUDA device."""
        if self.game_device == 'cpu':
            return 'cpu'
        from ..policies.device import resolve_device

        unsupported = device_unsupported(spec, camera_reward, opponent)
        if self.game_device == 'auto':
            on_gpu = resolve_device(self.device).type == 'cuda'
            return 'cuda' if on_gpu and not unsupported and device_game_available() else 'cpu'
        if unsupported:
            raise ValueError(f'--game-device cuda: {unsupported[0]} is not played on the device yet; use '
                             '--game-device cpu')
        if not device_game_available():
            raise ValueError('--game-device cuda: numba sees no CUDA device here (pip install "mate[gpu]" on a '
                             'machine with an NVIDIA GPU); use --game-device cpu')
        return 'cuda'

    def make_env(self, spec: PolicySpec, opponent=None, camera_reward: str = 'coverage') -> TrainingEnv:
        """The training envs (`TeamEnvConfig.make_env`), their games on the CPU or on the GPU where
        `resolved_game_device` says cuda (the networks' GPU: numba's current device)."""
        if self.resolved_game_device(spec, opponent, camera_reward) == 'cpu':
            return TeamEnvConfig.make_env(self, spec, opponent, camera_reward)
        from ..policies.device import resolve_device

        index = resolve_device(self.device).index if self.device.startswith('cuda') else None
        if index:                  # the games on the networks' GPU (numba's current device; the first by default)
            from numba import cuda

            cuda.select_device(index)
        return TeamEnvConfig.make_env(self, spec, opponent, camera_reward, device='cuda')


def mixed_camera_reward(coverage_rate, real_coverage_rate, camera_reward):
    """The population players' camera reward (docs/population.md) from one env step's (B,) arrays."""
    return 0.5 * coverage_rate + 0.5 * real_coverage_rate + 0.1 * camera_reward


def compress(x):
    """float32 x, with the entries beyond [-1, 1] (unbounded counters: bounties, freights, cargo counts up
    to 200) squashed logarithmically, sign(x) (1 + log|x|), so that they do not saturate the critic (numpy, or a
    tensor on its device)."""
    xp = array_namespace(x)
    magnitude = xp.abs(x)
    squashed = xp.sign(x) * (1.0 + xp.log(xp.maximum(magnitude, 1.0)))
    return xp.astype(xp.where(magnitude > 1.0, squashed, x), xp.float32)


def team_positions(state: np.ndarray, team: Team, counts) -> np.ndarray:
    """(B, N, 2) float64 world positions of `team`'s agents, cut from the global states (B, S) of games of `counts`
    = (Nc, Nt, No) (each agent's private state block starts with its x, y)."""
    nc, nt, _ = counts
    if team is Team.CAMERA:
        begin, count, width = PRESERVED_DIM, nc, CAMERA_STATE_DIM_PRIVATE
    else:
        begin, count, width = PRESERVED_DIM + CAMERA_STATE_DIM_PRIVATE * nc, nt, TARGET_STATE_DIM_PRIVATE
    rows = np.asarray(state)[:, begin:begin + count * width].reshape(len(state), count, width)
    return rows[..., :2].astype(np.float64)


OPPONENT_SEED_OFFSET = 7919
"""A training env of seed s seeds its opponent with s + 7919 (its row b with s + 7919 + b), apart from the games'."""


def greedy_opponent(team: Team, num_envs: int, counts, seed):
    """The default opponent of a team in training: the other team's greedy agents (`mate.teams.GreedyTeam`, draw
    for draw the Python agents; row b seeded seed + b)."""
    return GreedyTeam(Team.TARGET if team is Team.CAMERA else Team.CAMERA, num_envs, counts, seed=seed)


def device_unsupported(spec: PolicySpec, camera_reward: str = 'coverage', opponent=None) -> list[str]:
    """The settings of a training env that the games on a CUDA device cannot play, in the words of the command line
    (empty: it plays them all)."""
    found = []
    if spec.action == 'discrete':
        found.append("'discrete' actions (a toy task)")
    if camera_reward != 'coverage':
        found.append(f'the {camera_reward!r} camera reward')
    if opponent is not None:
        found.append('an opponent other than the greedy rules')
    return found


@functools.cache
def device_game_available() -> bool:
    """Whether numba sees a CUDA device (or its simulator) to play the games on."""
    try:
        from numba import cuda
    except ImportError:
        return False
    return bool(cuda.is_available())


class TrainingEnv:
    """B games in which a policy of `spec` plays its team against a batched opponent (module docstring), on the CPU
    (numpy arrays in and out) or on a CUDA device (`device='cuda'`: torch tensors on it in and out; only the
    decision's episode records come to the host).

    `reset(seed)` -> (obs (B, N, D) float32, state (B, S) float32).
    `step(actions)` -> (obs, state, reward, done (B,), truncated (B,), info). Actions: what the team holds for the
    decision, (B, N, heads) int choices (or (B, N) for one head) or (B, N, 2) continuous shares in [-1, 1] (values
    outside are clipped, as the env's action box would). Reward (B,) the team's, or (B, N) per agent with
    `credit` 'difference' or 'own'; done covers both ends of an episode, `truncated` the horizon cuts, and info holds
    `final_obs` / `final_state` (rows valid where done, zeros elsewhere), `coverage` (B,) mean env-step coverage of
    the decision, and `episodes`: a host list of finished-episode dicts (`coverage`: step-mean coverage rate,
    `return`: the learner's reward summed, `raw_return`: the target team's raw reward summed and divided by the
    preset's maximum target-team episode reward (the paper's normalised reward), `length`), in the order the
    episodes ended (env step, then game).

    The same code on both devices (`mate.core.arrays`): the single-team env of the device (`mate.make_team_vec`), the
    spec's pipeline (`PolicySpec.features`, `decode`, `allowed`), the sighting memory and `compress` serve numpy
    arrays and torch tensors. With the device team's host twin as the CPU env's opponent (`HostTeam`) the two play
    the same games, number for number (tests/learn/test_device_envs.py, under numba's CUDA simulator).

    Args:
        spec: the trained policy's spec (team, game, frame skip, observation features, action kind).
        num_envs: B.
        horizon: env steps per episode (None: 500 decisions).
        seed: seed of `reset()` without a seed, and of the opponent (seed + 7919).
        credit: 'team', 'difference' (cameras) or 'own' (targets).
        camera_reward: 'coverage' or 'mixed' (cameras, credit 'team'; the CPU only).
        opponent: a factory `f(num_envs, counts, seed)` of the other team (default: the greedy rules; the CPU
            only: on a device the greedy device team plays).
        device: None or 'cpu' (numpy), or 'cuda' / 'cuda:N' (the games as CUDA kernels, torch tensors).
        block: threads per CUDA block (device only; None: the core's default).
        **overrides: config keys of the game (`mate.make_vec`'s).
    """

    def __init__(self, spec: PolicySpec, num_envs: int = 64, horizon: int | None = None, seed: int | None = 0,
                 credit: str = 'team', camera_reward: str = 'coverage', opponent=None, device: str | None = None,
                 block: int | None = None, **overrides) -> None:
        team = as_team(spec.team)
        if credit not in CREDITS:
            raise ValueError(f'credit must be one of {CREDITS}, got {credit!r}')
        if camera_reward not in CAMERA_REWARDS:
            raise ValueError(f'camera_reward must be one of {CAMERA_REWARDS}, got {camera_reward!r}')
        if camera_reward != 'coverage' and (team is not Team.CAMERA or credit != 'team'):
            raise ValueError(f"camera_reward {camera_reward!r} is a camera team reward (credit 'team' only)")
        if credit == 'difference' and team is not Team.CAMERA:
            raise ValueError("credit 'difference' (each camera's own share of the coverage) exists for cameras only")
        if credit == 'own' and team is not Team.TARGET:
            raise ValueError("credit 'own' (each target's own part of the team reward) exists for targets only")
        self.tensors = device is not None and str(device) != 'cpu'
        """Whether the games are on a CUDA device (the trainer passes actions as tensors and takes tensors back)."""
        games = dict(reward='team' if credit == 'team' else credit, max_episode_steps=horizon or 500 * spec.frame_skip,
                     observation_dtype=np.float32, autoreset_mode='next_step', **overrides)
        if self.tensors:
            unsupported = device_unsupported(spec, camera_reward, opponent)
            if unsupported:
                raise ValueError(f'{unsupported[0]} is not played on the device yet; use --game-device cpu')
            from ..core.device import BLOCK

            games.update(device=device, block=block or BLOCK)
        else:
            games['opponent'] = opponent or (lambda n, counts, s: greedy_opponent(team, n, counts, s))
        self.spec, self.team, self.credit, self.camera_reward = spec, team, credit, camera_reward
        self.frame_skip = spec.frame_skip
        self.horizon = int(horizon or 500 * spec.frame_skip)
        self.num_envs = int(num_envs)
        self.envs = make_team_vec(resolve_config(spec.env_id, spec.config), team, self.num_envs, **games)
        self.vec = self.envs.vec
        self.counts = tuple(self.envs.counts)
        spec.check_game(team, self.counts, 'the policy spec')
        self.num_agents = spec.num_agents
        self.obs_dim, self.state_dim = spec.obs_dim, self.vec.single_state_space.shape[0]
        self.action_heads, self.action_choices, self.num_actions = spec.heads, spec.choices, spec.num_actions
        self._seed = seed
        self._opponent_seed = None if seed is None else seed + OPPONENT_SEED_OFFSET
        self._state_scaling = box_scaling(self.vec.single_state_space)
        self._max_reward = float(self.vec.params.max_target_team_episode_reward)
        like = self.vec.world.target_reward                # an array of the games' kind, on their device
        self.device = getattr(like, 'device', None) if self.tensors else None
        self.memory = SightingMemory(self.num_envs, self.counts, spec.memory, like=like) if spec.memory else None
        self._return = self._zeros(self.num_envs)      # the learner's reward summed (the game's statistics: the core's)
        self._raw = self._before = None                # the team's raw observations now and one env step before

    # ------------------------------------------------------------------ helpers
    def _zeros(self, *shape, dtype=np.float64):
        """Zeros of the games' kind: a numpy array, or a tensor made on their device (no copy from the host)."""
        if not self.tensors:
            return np.zeros(shape, dtype=dtype)
        import torch

        return torch.zeros(shape, dtype=torch.from_numpy(np.zeros(0, dtype)).dtype, device=self.device)

    def _enhanced(self, raw):
        """The team's raw observations (B, N, D) as it sees them: unchanged, or (full observability) a copy with
        every record filled (`enhance_observations`: every entity's public state and flag 1; targets: the true empty
        warehouses). The opponent keeps its partial view."""
        if not self.spec.full_observability:
            return raw
        camera = self.team is Team.CAMERA
        camera_obs, target_obs = self.vec.observations
        own = copied(raw)
        enhance_observations(own if camera else camera_obs, target_obs if camera else own, self.vec.obstacle_states,
                             empty_warehouses(self.vec.remaining_cargoes), *self.counts, camera=camera,
                             target=not camera)
        return own

    def _features(self, raw, memory=None, before=None):
        """The spec's features of raw observations (B, N, D), with the team's memory now (or `memory` = (age,
        location) kept from an earlier step) and the observations of the env step before (or `before`)."""
        columns = None
        if self.memory is not None:
            columns = self.memory.columns(raw, *(memory or (self.memory.age, self.memory.location)))
        return self.spec.features(raw, columns, self._before if before is None else before)

    def _state(self, state=None):
        """The learner's global state (B, S) float32: the games' state now (or `state`) rescaled with the state-space
        bounds, its unbounded counters log-compressed."""
        state = self.vec.state() if state is None else state
        return compress(scale_in_place(float64_copy(state), self._state_scaling))

    def _team_reward(self, infos):
        """(B,) the learner's team reward of the env step just played: cameras the coverage rate (or the population
        players' mixed reward), targets the raw team reward."""
        target_reward = self.vec.world.target_reward
        if self.team is Team.TARGET:
            return target_reward
        if self.camera_reward == 'coverage':
            return infos['coverage_rate']
        return mixed_camera_reward(infos['coverage_rate'], infos['real_coverage_rate'], -target_reward)

    def _play(self, own_actions, previous, restarting):
        """One env step of the games (the opponent acts inside the single-team env and restarts with its rows);
        returns (the team's raw observations as it sees them, the single-team env's rewards, terminated, truncated,
        infos). Keeps the team's raw observations of the step before (`previous`; for the rows of `restarting`,
        which start an episode now, their first ones: no motion yet) and updates the sighting memory."""
        previous = copied(previous) if self.spec.velocity else None    # (the env overwrites its buffers)
        raw, rewards, terminated, truncated, infos = self.envs.step_games(own_actions)
        raw = self._enhanced(raw)
        if previous is not None:
            self._before = array_namespace(raw).where(restarting[:, None, None], raw, previous)
        if self.memory is not None:
            if maybe_any(restarting):
                self.memory.forget(restarting)
            self.memory.tick()
            self.memory.observe_team(raw)
        return raw, rewards, terminated, truncated, infos

    # ------------------------------------------------------------------ API
    @property
    def opponent(self):
        """The other team's batched team (played inside `self.envs`, the public `mate.SingleTeamVecEnv`)."""
        return self.envs.opponent

    @property
    def raw_observations(self):
        """(B, N, D) unprocessed observations of the trained team at the current decision (do not modify)."""
        return self._raw

    def positions(self) -> np.ndarray:
        """(B, N, 2) float64 host array: world positions of the trained team's agents at the current decision, cut
        from the global state as `RestrictedCommunicationRange` reads them (the training channel's range test)."""
        return team_positions(host_array(self.vec.state()), self.team, self.counts)

    def allowed_actions(self, features):
        """The spec's allowed choices (..., N, heads, choices) of features (..., N, D); None when all are."""
        return self.spec.allowed(features)

    def observations(self):
        """(features (B, N, D), state (B, S)) of the current decision (as `reset` and `step` return them)."""
        return self._features(self._raw), self._state()

    def reset(self, seed: int | None = None):
        seed = self._seed if seed is None else seed
        raw, _ = self.envs.reset(seed=seed, opponent_seed=None if seed is None else self._opponent_seed)
        self._raw = copied(self._enhanced(raw))
        self._before = copied(self._raw) if self.spec.velocity else None
        if self.memory is not None:
            self.memory.forget()
            self.memory.tick()
            self.memory.observe_team(self._raw)
        self._return[...] = 0.0
        return self.observations()

    def _held(self, actions):
        """The decision's actions as (B, N, heads) choices or (B, N, 2) continuous shares clipped to [-1, 1], on the
        games' device."""
        B, N = self.num_envs, self.num_agents
        if self.tensors:
            import torch

            actions = torch.as_tensor(actions, device=self.device)
            actions = actions.to(torch.float64) if self.spec.continuous else actions.to(torch.long)
        else:
            actions = np.asarray(actions)
        xp = array_namespace(actions)
        if self.spec.continuous:
            return xp.minimum(xp.maximum(xp.reshape(actions, (B, N, 2)), -1.0), 1.0)
        return xp.reshape(actions, (B, N, self.action_heads))

    def step(self, actions):
        B, N = self.num_envs, self.num_agents
        held = self._held(actions)
        xp = array_namespace(held)
        own_actions = None if self.spec.closed_loop else self.spec.decode(held, self._raw)
        reward = self._zeros(*((B,) if self.credit == 'team' else (B, N)))
        coverage, counted = self._zeros(B), self._zeros(B)
        done, truncated = self._zeros(B, dtype=bool), self._zeros(B, dtype=bool)
        final_raw = final_state = None                  # the ended rows' last observations and states
        final_before = final_memory = None
        ended_at = self._zeros(B, dtype=np.int64)       # the env step a row's episode ended at
        record = {name: self._zeros(B) for name in ('coverage', 'length', 'return', 'raw_return')}
        restarting = self._zeros(B, dtype=bool)          # rows whose episode ended at the last env step
        own_raw = self._raw
        for k in range(self.frame_skip):
            if self.spec.closed_loop:      # the executor re-aims at every env step from the fresh observation
                own_actions = self.spec.decode(held, own_raw)
            raw, rewards, terminated, truncated_now, infos = self._play(own_actions, own_raw, restarting)
            live = ~done & ~restarting
            team_reward = self._team_reward(infos)
            if self.credit == 'team':
                reward += xp.where(live, team_reward, 0.0)
            else:                          # each agent's part: a target's own reward, a camera's difference credit
                reward += xp.where(live[:, None], rewards, 0.0)
            coverage += xp.where(live, infos['coverage_rate'], 0.0)
            counted += live
            self._return += xp.where(live, team_reward, 0.0)
            ended = live & (terminated | truncated_now)
            if maybe_any(ended):
                final_raw = xp.where(ended[:, None, None], raw, raw if final_raw is None else final_raw)
                final_state = xp.where(ended[:, None], self.vec.state(),
                                       0.0 if final_state is None else final_state)
                if self.spec.velocity:
                    final_before = xp.where(ended[:, None, None], self._before,
                                            self._before if final_before is None else final_before)
                if self.memory is not None:
                    age, location = self.memory.age, self.memory.location
                    kept = (age, location) if final_memory is None else final_memory
                    final_memory = (xp.where(ended[:, None], age, kept[0]),
                                    xp.where(ended[:, None, None], location, kept[1]))
                truncated |= ended & truncated_now & ~terminated
                done |= ended
                episode = infos[EPISODE_INFO]      # the episode's statistics, as the core counted them
                for name, value in (('coverage', episode['coverage_rate']), ('length', episode['l']),
                                    ('return', self._return),
                                    ('raw_return', episode['target_return'] / self._max_reward)):
                    record[name] = xp.where(ended, xp.astype(value, xp.float64), record[name])
                ended_at = xp.where(ended, k, ended_at)
                self._return = xp.where(ended, 0.0, self._return)
            restarting = ended
            own_raw = raw
        if bool(xp.any(restarting)):   # ended at the last env step: restart now so that the next decision is clean
            raw = self._play(own_actions, own_raw, restarting)[0]
        self._raw = copied(raw)
        info = dict(final_obs=self._final(done, final_raw, lambda: self._features(final_raw, final_memory,
                                                                                   final_before), (B, N, self.obs_dim)),
                    final_state=self._final(done, final_state, lambda: self._state(final_state), (B, self.state_dim)),
                    coverage=coverage / xp.maximum(counted, 1.0), episodes=self._episodes(done, ended_at, record))
        features, state = self.observations()
        return features, state, reward, done, truncated, info

    def _final(self, done, kept, compute, shape: tuple[int, ...]):
        """`final_obs` (B, N, D) or `final_state` (B, S) of a decision (`shape`), float32: `compute()` of the rows
        `kept` at their episode's end where `done`, zeros elsewhere (and everywhere when no row ended)."""
        if kept is None:                 # (host arrays only: on a device every step keeps its rows)
            return self._zeros(*shape, dtype=np.float32)
        values = compute()
        mask = done[:, None, None] if values.ndim == 3 else done[:, None]
        return array_namespace(values).where(mask, values, 0.0)

    @staticmethod
    def _episodes(done, ended_at, record) -> list[dict]:
        """The finished episodes' records (host dicts), in the order they ended (env step, then row)."""
        done = host_array(done)             # (on a device: one read back, and the records' when a row ended)
        rows = np.flatnonzero(done)
        if rows.size == 0:
            return []
        order = rows[np.argsort(host_array(ended_at)[rows] * done.shape[0] + rows, kind='stable')]
        values = {name: host_array(value)[order].tolist() for name, value in record.items()}
        return [dict(coverage=values['coverage'][i], length=int(values['length'][i]),
                     **{'return': values['return'][i]}, raw_return=values['raw_return'][i])
                for i in range(len(values['coverage']))]

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict:
        """Everything the batch's future depends on, as host arrays (see the module docstring): the games and the
        opponent (the single-team env's `state_dict`), the sighting memory, the observations of the env step
        before and the episodes' sums; `games_on` says where the games were played."""
        memory = None if self.memory is None else dict(location=host_copy(self.memory.location),
                                                       age=host_copy(self.memory.age))
        return dict(games=self.envs.state_dict(), games_on='cuda' if self.tensors else 'cpu', memory=memory,
                    before=host_copy(self._before), sums=dict(returns=host_copy(self._return)))

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from envs of the same spec, size and opponent kind; a state of
        an earlier version's CPU env loads too)."""
        on = state.get('games_on', 'cuda' if 'device' in state else 'cpu')
        here = 'cuda' if self.tensors else 'cpu'
        if on != here:
            where = 'a GPU' if on == 'cuda' else 'the CPU'
            raise ValueError(f'this checkpoint holds the state of games played on {where}; resume it with '
                             f'--game-device {on}')
        games = state.get('games') or dict(vec=state['vec'], opponent=state['opponent'],
                                           pending=state.get('pending', False))   # (older: none pending)
        self.envs.load_state_dict(games)
        if self.memory is not None:
            self.memory.location = as_kind_of(np.array(state['memory']['location']), self._return)
            self.memory.age = as_kind_of(np.array(state['memory']['age']), self._return)
        self._raw = copied(self._enhanced(self.vec.observations[0 if self.team is Team.CAMERA else 1]))
        self._before = None if state['before'] is None or not self.spec.velocity else as_kind_of(
            np.array(state['before']), self._return)
        sums = state['sums']
        self._return = as_kind_of(np.array(sums['returns'], dtype=np.float64), self._return)
        vec_state = games.get('vec', {})
        if 'world' in vec_state and 'coverage_rate_sum' not in vec_state['world'] and 'coverage' in sums:
            self.vec.world.coverage_rate_sum[...] = sums['coverage']      # an earlier version's state


TeamVecEnv = TrainingEnv
"""The earlier name of `TrainingEnv` (until 2026-12-02), kept for code written against it."""
