"""`MultiAgentTracking`: the Gymnasium-style two-team environment (one world row of the core).

The class docstring of `MultiAgentTracking` describes the game: spaces, the accepted action forms,
rewards, episode end and arguments (`help(mate.MultiAgentTracking)`, or the API page of the docs).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .. import spaces as mate_spaces
from ..config import read_config
from ..constants import (
    WAREHOUSE_RADIUS,
    WAREHOUSES,
    camera_observation_dim,
    state_dim,
    target_observation_dim,
)
from ..core import engine
from ..core.params import params_from_config
from ..core.snapshot import get_snapshot, goal_bits, set_snapshot
from ..core.world import empty_world, episode_statistics, obstacle_states, target_headings
from ..messages import Message, MessageChannel, Team

__all__ = ['MultiAgentTracking', 'GameDescription']

_ONE = np.ones(1, dtype=bool)

# Read-only views of world fields (row 0), under the original's attribute names.
_WORLD_VIEWS = {
    'tracked_steps': 'target_tracked_steps', 'target_steps': 'target_steps', 'freights': 'target_freight',
    'bounties': 'target_bounty', 'target_goals': 'target_goal', 'target_capacities': 'target_capacity',
    'target_dones': 'target_done', 'target_is_colliding': 'target_is_colliding',
    'remaining_cargoes': 'remaining_cargoes',
    'awaiting_cargo_counts': 'awaiting_cargo_counts', 'camera_target_view_mask': 'camera_target_view_mask',
    'camera_obstacle_view_mask': 'camera_obstacle_view_mask', 'camera_camera_view_mask': 'camera_camera_view_mask',
    'target_camera_view_mask': 'target_camera_view_mask', 'target_obstacle_view_mask': 'target_obstacle_view_mask',
    'target_target_view_mask': 'target_target_view_mask',
}
_WORLD_SCALARS = {
    'episode_step': int, 'num_delivered_cargoes': int, 'coverage_rate': float, 'real_coverage_rate': float,
    'mean_transport_rate': float, 'target_team_episode_reward': float, 'delayed_target_team_episode_reward': float,
}


ACTION_FIELDS = {'camera': '[rotate, zoom]', 'target': '[dx, dy]'}
"""What one agent's action row holds, per team (for error messages)."""


def team_shape_error(team: str, expected: tuple[int, ...], got, batched: str = '', alternative=None) -> str:
    """The one-line message refusing `team`'s actions of shape `got` (a shape, or a description):
    `camera joint action must have shape (4, 2) (4 cameras x [rotate, zoom]); got (2, 4)`.
    `batched` names the leading axes of a vector env's actions (`'num_envs x '`); `alternative` is
    another accepted shape."""
    count = expected[-2]
    what = f'{team} actions' if batched else f'{team} joint action'
    also = '' if alternative is None else f' or {alternative}'
    return (f'{what} must have shape {expected} ({batched}{count} {team}{"" if count == 1 else "s"} x '
            f'{ACTION_FIELDS[team]}){also}; got {got}')


def agent_action(agent: str, action, shape: tuple[int, ...]) -> np.ndarray:
    """One agent's action (`agent` named `camera_<i>` or `target_<i>`, as the PettingZoo and RLlib
    adapters name them) as a float64 array of `shape`; ValueError naming the agent otherwise."""
    fields = ACTION_FIELDS['camera' if agent.startswith('camera') else 'target']
    try:
        array = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'action of {agent} must be an array of shape {shape} {fields}; got {action!r} '
                         f'({exc})') from None
    if array.shape != shape:
        raise ValueError(f'action of {agent} must have shape {shape} {fields}; got {array.shape}')
    return array


def _row_view(field: str):
    def get(self):
        view = getattr(self._world, field)[0].view()
        view.flags.writeable = False
        return view
    return property(get, doc=f'Current `{field}` of the world (read-only view).')


def _row_scalar(field: str, kind):
    return property(lambda self: kind(getattr(self._world, field)[0]), doc=f'Current `{field}`.')


class GameDescription:
    """Read-only facts of the configured game, for classes holding `params` and `config`
    (the single env and the vector env)."""

    params: Any
    config: dict

    @property
    def name(self) -> str:
        return self.config['name']

    @property
    def num_cameras(self) -> int:
        return self.params.num_cameras

    @property
    def num_targets(self) -> int:
        return self.params.num_targets

    @property
    def num_obstacles(self) -> int:
        return self.params.num_obstacles

    @property
    def max_episode_steps(self) -> int:
        return self.params.max_episode_steps


class MultiAgentTracking(GameDescription, gym.Env):
    """The two-team tracking game as a Gymnasium env: one world, cameras and targets acting together.

    Cameras (fixed in place, rotating and zooming) try to keep targets in view; targets carry cargo
    between the four corner warehouses. Both teams act at every step. `mate.make(id)` builds one
    from a registered ID; the environment pages of the docs describe the game in full.

    **Action space.** `action_space` is `Tuple(camera_joint_action_space, target_joint_action_space)`,
    each a `mate.spaces.TeamSpace` of `Nc` (or `Nt`) `Box(2)` that samples the whole team in one draw.
    A camera acts with `[rotate, zoom]` in degrees, within +-`rotation_step` and +-`zooming_step`; a
    target with a displacement `[dx, dy]` within +-`step_size`, which the dynamics shorten to the
    target's speed (`step_size / capacity`). `step((camera_actions, target_actions))` takes each team's
    actions as an `(N, 2)` array of any real dtype (one row per agent, in slot order), a sequence of
    N pairs, or a sample of the team's space. Any other shape, a flat `(2N,)` vector included, raises
    a `ValueError` naming the team, the expected shape and the shape given: nothing is reshaped.
    Values outside the bounds are clipped by the dynamics; NaN or inf is refused. A refused action
    leaves the env unchanged.

    **Observation space.** `observation_space` is a `Tuple` of the teams' `Tuple`s of per-agent `Box`es
    (`camera_observation_space`, `target_observation_space`); `reset` and `step` return each team's
    observations as one float64 array, `(Nc, D_c)` and `(Nt, D_t)`, laid out as `mate.spaces`
    describes. `state()` is the global state vector (`state_space`).

    **Step.** `env.step((camera_actions, target_actions))` returns
    `((camera_obs, target_obs), (camera_reward, target_reward), terminated, truncated,
    (camera_infos, target_infos))`, with one info dict per agent (`raw_reward`,
    `normalized_raw_reward`, `coverage_rate`, `real_coverage_rate`, `mean_transport_rate`,
    `num_delivered_cargoes`, `messages` and the communication edges).

    **Rewards.** Team rewards, zero-sum: `camera_reward == -target_reward`. With `reward_type: dense`
    (the presets) the targets lose a point each step per tracked target whose bounty is not used up
    and gain the freight plus the bounty left of each cargo unit they deliver; `sparse` pays the
    same total at delivery.

    **Episode end.** `terminated` once every cargo unit is delivered; `truncated` after exactly
    `max_episode_steps` steps (never on the same step as `terminated`). `step` before the first
    `reset` raises `RuntimeError`.

    **Version history.** v0: the behaviour of the original MATE, with the differences listed on the
    docs' differences page.

    Args:
        config: a preset name (`'MATE-4v8-9'`), a YAML/JSON path or a dict (see `mate.read_config`);
            None: the default preset, or an empty configuration when overrides are given (a quirk
            of the original MATE).
        render_mode: None, `'rgb_array'` (`render()` returns an `(800, 800, 3)` uint8 frame) or
            `'human'` (a pygame window); see `mate.envs.render`.
        **overrides: keys deep-merged into the configuration (e.g. `max_episode_steps=1000`).
    """

    metadata = {'render_modes': ['human', 'rgb_array'], 'render_fps': 60}

    def __init__(self, config: Any = None, render_mode: str | None = None, **overrides: Any) -> None:
        if render_mode is not None and render_mode not in self.metadata['render_modes']:
            raise ValueError(f'render_mode={render_mode!r} is not supported; use None, '
                             f"{' or '.join(map(repr, self.metadata['render_modes']))}")
        self.render_mode = render_mode
        self.render_fps = self.metadata['render_fps']  # 'human' windows refresh at most this often
        self.render_hud = True  # frames show the heads-up line (step, coverage, cargo); see mate.envs.render
        self.render_callbacks: dict = {}
        self.viewer = None
        self.config = read_config(config, **overrides)
        self.params = p = params_from_config(self.config)
        self._world = empty_world(p, 1)
        nc, nt, no = p.num_cameras, p.num_targets, p.num_obstacles
        self._camera_obs = np.zeros((1, nc, camera_observation_dim(nc, nt, no)))
        self._target_obs = np.zeros((1, nt, target_observation_dim(nc, nt, no)))
        self._camera_actions, self._target_actions = np.zeros((1, nc, 2)), np.zeros((1, nt, 2))
        self._step_world = None  # the compiled step bound to these arrays, made by the first step
        self._channel = MessageChannel(nc, nt)
        self._needs_reset = True
        self._make_spaces()

    # ------------------------------------------------------------------ spaces
    def _make_spaces(self) -> None:
        p = self.params
        counts = (p.num_cameras, p.num_targets, p.num_obstacles)
        rot, zoom = (p.camera_rotation_step, p.camera_zooming_step) if p.num_cameras else (0.0, 0.0)
        self.camera_action_space = spaces.Box(np.array([-rot, -zoom]), np.array([rot, zoom]), dtype=np.float64)
        s = p.target_step_size
        self.target_action_space = spaces.Box(np.array([-s, -s]), np.array([s, s]), dtype=np.float64)
        self.camera_joint_action_space = mate_spaces.TeamSpace(self.camera_action_space, p.num_cameras)
        self.target_joint_action_space = mate_spaces.TeamSpace(self.target_action_space, p.num_targets)
        self.action_space = spaces.Tuple((self.camera_joint_action_space, self.target_joint_action_space))
        self.camera_observation_space = mate_spaces.camera_observation_space_of(*counts)
        self.target_observation_space = mate_spaces.target_observation_space_of(*counts)
        self.camera_joint_observation_space = mate_spaces.TeamSpace(self.camera_observation_space, p.num_cameras)
        self.target_joint_observation_space = mate_spaces.TeamSpace(self.target_observation_space, p.num_targets)
        self.observation_space = spaces.Tuple((self.camera_joint_observation_space,
                                               self.target_joint_observation_space))
        self.state_space = mate_spaces.state_space_of(*counts)
        self.camera_state_space_public = mate_spaces.camera_state_space(private=False)
        self.camera_state_space_private = mate_spaces.camera_state_space(private=True)
        self.target_state_space_public = mate_spaces.target_state_space(private=False)
        self.target_state_space_private = mate_spaces.target_state_space(private=True)
        self.obstacle_state_space = mate_spaces.obstacle_state_space()

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start a new episode; returns ((camera_obs, target_obs), (camera_infos, target_infos)).

        `seed` re-seeds the episode stream; without it the stream continues (a never-seeded
        env starts from OS entropy).
        """
        super().reset(seed=seed)
        if seed is not None or self._needs_seed():
            engine.seed_rows(self._world, _ONE, [seed])
        engine.reset(self.params, self._world, _ONE, self._camera_obs, self._target_obs)
        self._channel.reset()
        self._needs_reset = False
        return self._observations(), self._infos(0.0)

    def __getstate__(self) -> dict:
        """Copies and pickles rebind the compiled step to their own arrays on their first step."""
        return {**self.__dict__, '_step_world': None}

    def _needs_seed(self) -> bool:
        return self._world.rng[0, 0] == 0 and self._world.rng[0, 1] == 0

    def step(self, action):
        """Advance one step with (camera_actions (Nc, 2), target_actions (Nt, 2)); see the class docstring
        for the accepted action forms and the return value."""
        if self._needs_reset:
            raise RuntimeError('MultiAgentTracking: call reset() before step()')
        self._camera_actions[...], self._target_actions[...] = self._parse_action(action)
        if self._step_world is None:
            self._step_world = engine.bind_step(self.params, self._world, self._camera_actions, self._target_actions,
                                                self._camera_obs, self._target_obs)
        self._step_world()
        w = self._world
        target_reward = float(w.target_reward[0])
        infos = self._infos(target_reward)
        self._channel.end_step()
        return (self._observations(), (-target_reward, target_reward), bool(w.terminated[0]),
                bool(w.truncated[0]), infos)

    def _parse_action(self, action) -> tuple[np.ndarray, np.ndarray]:
        try:
            camera_action, target_action = action
        except (TypeError, ValueError):
            raise ValueError('action must be a pair (camera_joint_action, target_joint_action), '
                             f'got {type(action).__name__}') from None
        return (self._team_action(camera_action, self.params.num_cameras, 'camera', self.camera_action_space),
                self._team_action(target_action, self.params.num_targets, 'target', self.target_action_space))

    @staticmethod
    def _team_action(value, count: int, team: str, box: spaces.Box) -> np.ndarray:
        """A team's actions as a (1, count, 2) float64 array; ValueError for any other shape."""
        try:   # a TeamSpace sample carries its stacked array (no re-stacking of the per-agent views)
            array = np.asarray(value.array if type(value) is mate_spaces.TeamSample else value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            if 'inhomogeneous' in str(exc):   # rows of different lengths
                raise ValueError(team_shape_error(team, (count, 2), 'a ragged sequence')) from None
            raise ValueError(f'{team} joint action is not numeric: {exc}') from None
        if array.shape != (count, 2):
            if not (count == 0 and array.size == 0):   # an empty sequence for a team without agents
                raise ValueError(team_shape_error(team, (count, 2), array.shape))
            array = array.reshape(0, 2)
        if not np.isfinite(array).all():
            bad = sorted({int(i) for i in np.argwhere(~np.isfinite(array))[:, 0]})
            raise ValueError(f'{team} joint action contains NaN or inf (agents {bad}); every entry must be '
                             f'finite (bounds {box.low.tolist()}..{box.high.tolist()}; larger values are clipped)')
        return array[None]

    def _observations(self) -> tuple[np.ndarray, np.ndarray]:
        return self._camera_obs[0].copy(), self._target_obs[0].copy()

    def _infos(self, target_reward: float) -> tuple[list[dict], list[dict]]:
        w = self._world
        shared = {
            'coverage_rate': float(w.coverage_rate[0]),
            'real_coverage_rate': float(w.real_coverage_rate[0]),
            'mean_transport_rate': float(w.mean_transport_rate[0]),
            'num_delivered_cargoes': int(w.num_delivered_cargoes[0]),
            **episode_statistics(self.params, w, row=0),
        }
        return (self._team_infos(Team.CAMERA, -target_reward, shared),
                self._team_infos(Team.TARGET, target_reward, shared))

    def _team_infos(self, team: Team, reward: float, shared: dict) -> list[dict]:
        buffers, out_edges, in_edges = self._channel.step_summary(team)
        normalized = reward / self.params.max_target_team_episode_reward
        infos = []
        for messages, out, into in zip(buffers, out_edges, in_edges):   # (a copy and five stores: the fastest way)
            info = shared.copy()
            info['raw_reward'], info['normalized_raw_reward'] = reward, normalized
            info['messages'], info['out_communication_edges'], info['in_communication_edges'] = messages, out, into
            infos.append(info)
        return infos

    # ------------------------------------------------------------------ world access
    def joint_observation(self) -> tuple[np.ndarray, np.ndarray]:
        """Both teams' joint observations built from the current world (refreshes coverage)."""
        engine.observe(self.params, self._world, self._camera_obs, self._target_obs)
        return self._observations()

    def state(self) -> np.ndarray:
        """The global state vector (29 + 9 Nc + 16 Nt + 3 No,), float64."""
        p = self.params
        out = np.empty((1, state_dim(p.num_cameras, p.num_targets, p.num_obstacles)))
        engine.global_states(p, self._world, out)
        return out[0]

    def get_world(self) -> dict:
        """A snapshot of the world as a dict of fresh arrays (see `mate.core.snapshot`)."""
        return get_snapshot(self.params, self._world, 0)

    def set_world(self, snapshot: dict) -> None:
        """Load a snapshot; recomputes view masks, camera->obstacle flags and coverage, and clears
        message queues. Invalid snapshots raise `SnapshotError` and leave the env unchanged."""
        set_snapshot(self.params, self._world, 0, snapshot)
        engine.refresh(self.params, self._world, _ONE)
        engine.observe(self.params, self._world, self._camera_obs, self._target_obs)
        self._channel.end_step()
        self._needs_reset = False

    # ----------------------------------------------------------- rendering (drawing lives in mate/envs/render.py)
    def render(self, onetime_callbacks=()):
        """Draw the current world: an (800, 800, 3) uint8 array in 'rgb_array' mode, None in
        'human' mode. Registered callbacks, then `onetime_callbacks`, are called as
        `callback(env, renderer)` and may draw with the renderer's primitives."""
        if self.render_mode is None:
            gym.logger.warn('render() called on an env made with render_mode=None; '
                            "pass render_mode='rgb_array' or 'human' to the constructor")
            return None
        if self.viewer is None:
            from .render import Renderer
            self.viewer = Renderer(self.render_mode, fps=self.render_fps)
        self.viewer.fps, self.viewer.hud = self.render_fps, self.render_hud
        return self.viewer.render(self, onetime_callbacks)

    def add_render_callback(self, name: str, callback) -> None:
        """Register `callback(env, renderer)`, called at every render (a name replaces its earlier entry)."""
        self.render_callbacks[name] = callback

    def close(self) -> None:
        """Close the render window, if any."""
        if self.viewer is not None:
            self.viewer.close()
            self.viewer = None

    # ------------------------------------------------------------------ communication
    def send_messages(self, messages: Message | list[Message]) -> None:
        """Send messages to teammates (a broadcast reaches every teammate, the sender included)."""
        self._channel.send(messages)

    def receive_messages(self, agent_id=None, agent=None):
        """Fetch queued messages: all of them (per team, per slot) or one agent's."""
        return self._channel.receive(agent_id, agent)

    def route_messages(self, messages) -> list[Message]:
        """The messages as they would be delivered (broadcasts expanded), without sending."""
        return self._channel.route(messages if not isinstance(messages, Message) else [messages])

    @property
    def camera_communication_edges(self) -> np.ndarray:
        return self._channel.edges(Team.CAMERA)

    @property
    def target_communication_edges(self) -> np.ndarray:
        return self._channel.edges(Team.TARGET)

    @property
    def camera_total_communication_edges(self) -> np.ndarray:
        return self._channel.total_edges(Team.CAMERA)

    @property
    def target_total_communication_edges(self) -> np.ndarray:
        return self._channel.total_edges(Team.TARGET)

    # ------------------------------------------------------------------ properties
    @property
    def num_warehouses(self) -> int:
        return len(WAREHOUSES)

    @property
    def camera_observation_dim(self) -> int:
        return self.camera_observation_space.shape[0]

    @property
    def target_observation_dim(self) -> int:
        return self.target_observation_space.shape[0]

    @property
    def tracked_bits(self) -> np.ndarray:
        """(Nt,) bool: targets tracked by at least one camera."""
        return self._world.camera_target_view_mask[0].any(axis=0)

    @property
    def target_goal_bits(self) -> np.ndarray:
        """(Nt, 4) int: units carried per destination warehouse."""
        return goal_bits(self._world, 0)

    @property
    def obstacle_states(self) -> np.ndarray:
        """(No, 3) obstacle [x, y, r] per slot."""
        return obstacle_states(self._world, 0)

    @property
    def preserved_data(self) -> np.ndarray:
        """The 13 preserved observation entries (own index 0)."""
        p = self.params
        return np.array([p.num_cameras, p.num_targets, p.num_obstacles, 0, *WAREHOUSES.ravel(), WAREHOUSE_RADIUS])

    def _section(self, section: str, key: str):
        if section not in self.config:
            raise KeyError(f'the configuration has no {section!r} section')
        return self.config[section][key]

    camera_min_viewing_angle = property(lambda self: self._section('camera', 'min_viewing_angle'))
    camera_max_sight_range = property(lambda self: self._section('camera', 'max_sight_range'))
    camera_rotation_step = property(lambda self: self._section('camera', 'rotation_step'))
    camera_zooming_step = property(lambda self: self._section('camera', 'zooming_step'))
    target_step_size = property(lambda self: self.config['target']['step_size'])
    target_sight_range = property(lambda self: self.config['target']['sight_range'])
    num_cargoes_per_target = property(lambda self: self.params.num_cargoes_per_target)
    targets_start_with_cargoes = property(lambda self: self.params.targets_start_with_cargoes)
    bounty_factor = property(lambda self: self.config['bounty_factor'])
    shuffle_entities = property(lambda self: self.params.shuffle_entities)
    obstacle_transmittance = property(lambda self: self.params.transmittance)
    high_capacity_target_split = property(lambda self: self.config['high_capacity_target_split'])
    num_high_capacity_targets = property(lambda self: self.params.num_high_capacity_targets)
    num_low_capacity_targets = property(lambda self: self.params.num_targets - self.params.num_high_capacity_targets)
    freight_scale = property(lambda self: self.params.freight_scale)
    bounty_scale = property(lambda self: self.params.bounty_scale)
    reward_scale = property(lambda self: self.params.reward_scale)
    max_target_team_episode_reward = property(lambda self: self.params.max_target_team_episode_reward)

    def __str__(self) -> str:
        def count(n: int, word: str) -> str:
            return f'{n} {word}{"s" if n > 1 else ""}'
        p = self.params
        return (f'<MultiAgentTracking>({count(p.num_cameras, "camera")}, {count(p.num_targets, "target")}, '
                f'{count(p.num_obstacles, "obstacle")})')

    @property
    def target_warehouse_distances(self) -> np.ndarray:
        """(Nt, 4) Euclidean distances from each target to the warehouse centres (world units)."""
        return np.linalg.norm(self._world.target_pos[0][:, None, :] - WAREHOUSES[None], axis=-1)

    @property
    def target_orientations(self) -> np.ndarray:
        """(Nt,) the direction each target faces (its last move), degrees in [-180, 180]."""
        return target_headings(self._world, 0)

    # ------------------------------------------------------------------ read by mate.wrappers (begin)
    @property
    def obstacle_states_flagged(self) -> np.ndarray:
        """(No, 4) obstacle [x, y, r, 1] per slot: every obstacle as a visible observation record."""
        return np.concatenate([self.obstacle_states, np.ones((self.params.num_obstacles, 1))], axis=1)

    @property
    def message_buffers(self) -> tuple[list[list[Message]], list[list[Message]]]:
        """(camera_lists, target_lists): the messages delivered to each agent since the last step (new lists)."""
        return self._channel.buffer(Team.CAMERA), self._channel.buffer(Team.TARGET)
    # ------------------------------------------------------------------ read by mate.wrappers (end)


for _name, _field in _WORLD_VIEWS.items():
    setattr(MultiAgentTracking, _name, _row_view(_field))
for _name, _kind in _WORLD_SCALARS.items():
    setattr(MultiAgentTracking, _name, _row_scalar(_name, _kind))
