"""Trivial batched tasks for the learners (the TrainingEnv interface): cues to match, remember or exchange, a
matrix game, continuous targets. Each has a `spec` (`toy_spec`): what its policy sees and does, for the trainers
(which replace its network settings with their own)."""

import numpy as np

from mate.policies.spec import PolicySpec


class ToyTask:
    """What every toy task shares: its `spec` (abstract discrete choices, or continuous actions) and the
    attributes of `TrainingEnv` that the trainers read."""

    team = 'camera'
    frame_skip = 1
    credit = 'team'
    action_heads = 1

    @property
    def action_choices(self) -> int:
        return self.num_actions

    @property
    def spec(self) -> PolicySpec:
        return toy_spec(self)


def toy_spec(task) -> PolicySpec:
    """The spec of a toy task: its sizes, 'discrete' choices (or 'continuous' actions), an MLP network."""
    continuous = getattr(task, 'continuous', False)
    return PolicySpec(team=task.team, env_id='toy', config=None, counts=task.counts, frame_skip=1,
                      action='continuous' if continuous else 'discrete', levels=0 if continuous else task.num_actions,
                      memory=0, velocity=False, full_observability=False,
                      network='independent' if continuous else 'mlp', hidden=(8,), activation='tanh', lstm=0,
                      obs_dim=task.obs_dim, state_dim=task.state_dim, num_agents=task.num_agents)


class CueMatching(ToyTask):
    """B envs x N agents; obs = one-hot of a random cue among A actions; team reward = fraction of agents
    whose action equals their cue; episodes of `length` decisions (the last one is a truncation)."""

    def __init__(self, num_envs=16, num_agents=2, num_actions=4, length=8, seed=0):
        self.num_envs, self.num_agents, self.num_actions, self.length = num_envs, num_agents, num_actions, length
        self.obs_dim = num_actions
        self.state_dim = num_agents * num_actions
        self.counts = (num_agents, 1, 0)
        self.rng = np.random.default_rng(seed)

    def _observe(self):
        self.cue = self.rng.integers(self.num_actions, size=(self.num_envs, self.num_agents))
        obs = np.eye(self.num_actions, dtype=np.float32)[self.cue]
        return obs, obs.reshape(self.num_envs, -1).copy()

    def reset(self, seed=None):
        self.t = 0
        return self._observe()

    def step(self, actions):
        reward = (np.asarray(actions) == self.cue).mean(axis=1).astype(np.float64)
        self.t += 1
        done = np.full(self.num_envs, self.t % self.length == 0)
        final_obs, final_state = self._observe()
        info = dict(final_obs=final_obs, final_state=final_state, coverage=reward,
                    episodes=[dict(coverage=0.0, length=self.length, **{'return': 0.0})] if done[0] else [])
        return final_obs, final_state, reward, done, done.copy(), info


class CueRecall(CueMatching):
    """Like CueMatching, but the cue is shown only at the first decision of an episode (then a blank
    observation with a 'later' bit) and stays the same for the whole episode: only a policy with memory
    can keep matching it. A memoryless policy scores at most (1 + (length - 1) / A) / length."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.obs_dim = self.num_actions + 1
        self.state_dim = self.num_agents * self.obs_dim

    def _show(self, first):
        obs = np.zeros((self.num_envs, self.num_agents, self.obs_dim), dtype=np.float32)
        if first:
            obs[..., :self.num_actions] = np.eye(self.num_actions, dtype=np.float32)[self.cue]
        else:
            obs[..., -1] = 1.0
        return obs, obs.reshape(self.num_envs, -1).copy()

    def _observe(self):
        if self.t % self.length == 0:
            self.cue = self.rng.integers(self.num_actions, size=(self.num_envs, self.num_agents))
        return self._show(self.t % self.length == 0)


class CueExchange(CueMatching):
    """Each agent's cue is drawn at an episode's start and kept for the whole episode, but it is shown, at every
    decision, only to a teammate: agent i sees the cue of agent i + 1 (mod N). The team reward is the fraction
    of agents whose action equals their own cue. An agent's observation says nothing about its own cue, so a
    policy without communication scores chance, 1 / A, whatever its memory; with messages read one decision
    later every decision but an episode's first can match: at best (1 / A + length - 1) / length."""

    def _observe(self):
        if self.t % self.length == 0:
            self.cue = self.rng.integers(self.num_actions, size=(self.num_envs, self.num_agents))
        shown = np.roll(self.cue, -1, axis=1)                      # shown[:, i] = cue[:, i + 1]
        obs = np.eye(self.num_actions, dtype=np.float32)[shown]
        return obs, obs.reshape(self.num_envs, -1).copy()


class OwnCueMatching(CueMatching):
    """CueMatching with each agent paid for its own match only: rewards (B, N), as `TrainingEnv` gives
    them with `credit='difference'`."""

    credit = 'difference'

    def step(self, actions):
        own = (np.asarray(actions) == self.cue).astype(np.float64)      # before the next cue is drawn
        obs, state, _, done, truncated, info = super().step(actions)
        return obs, state, own, done, truncated, info


class TwoStepGame(ToyTask):
    """The two-step cooperative game of the QMIX paper (Rashid et al. 2018, Fig. 3), for B envs at once.

    Both agents observe (and the state is) the one-hot of the stage: 1, 2A or 2B. At stage 1 the first
    agent's action picks the next stage (0 -> 2A, 1 -> 2B) and nobody is paid; at stage 2A every joint
    action pays 7; at 2B the payoff is [[0, 1], [1, 8]]. Episodes end after two decisions (terminal). The
    optimal joint policy earns 8; learners whose per-agent values average over an exploring partner value
    2B at (1 + 8) / 2 = 4.5 < 7 and settle for 7."""

    PAYOFF_2B = np.array([[0.0, 1.0], [1.0, 8.0]])

    def __init__(self, num_envs=16):
        self.num_envs, self.num_agents, self.num_actions = num_envs, 2, 2
        self.obs_dim, self.state_dim, self.counts = 3, 3, (2, 1, 0)
        self.stage = np.zeros(num_envs, dtype=np.int64)

    def _observe(self):
        state = np.eye(3, dtype=np.float32)[self.stage]
        return np.repeat(state[:, None], 2, axis=1), state

    def reset(self, seed=None):
        self.stage[:] = 0
        return self._observe()

    def step(self, actions):
        actions = np.asarray(actions)
        first = self.stage == 0
        reward = np.where(self.stage == 1, 7.0, self.PAYOFF_2B[actions[:, 0], actions[:, 1]])
        reward = np.where(first, 0.0, reward)
        done = ~first
        self.stage = np.where(first, 1 + actions[:, 0], 2)
        final_obs, final_state = self._observe()
        self.stage[done] = 0
        obs, state = self._observe()
        info = dict(final_obs=final_obs, final_state=final_state, coverage=reward,
                    episodes=[dict(coverage=0.0, length=2, **{'return': float(r)}) for r in reward[done]])
        return obs, state, reward, done, np.zeros_like(done), info


class ContinuousCue(ToyTask):
    """B envs x N agents with continuous actions in [-1, 1]^2: each agent sees a random point (its cue) and is
    paid, as a team, 1 - the mean distance of the agents' actions to their cues / 2; episodes of `length`
    decisions (the last a truncation). A learner's team reward rises from ~0.4 (uniform actions) towards 1."""

    team = 'target'
    continuous = True

    def __init__(self, num_envs=16, num_agents=2, length=8, seed=0):
        self.num_envs, self.num_agents, self.length = num_envs, num_agents, length
        self.num_actions, self.obs_dim, self.state_dim = 2, 2, 2 * num_agents
        self.counts = (1, num_agents, 0)
        self.rng = np.random.default_rng(seed)

    def _observe(self):
        self.cue = self.rng.uniform(-0.8, 0.8, size=(self.num_envs, self.num_agents, 2)).astype(np.float32)
        return self.cue.copy(), self.cue.reshape(self.num_envs, -1).copy()

    def reset(self, seed=None):
        self.t = 0
        return self._observe()

    def step(self, actions):
        distance = np.linalg.norm(np.asarray(actions) - self.cue, axis=-1).mean(axis=1)
        reward = 1.0 - distance / 2.0
        self.t += 1
        done = np.full(self.num_envs, self.t % self.length == 0)
        obs, state = self._observe()
        info = dict(final_obs=obs, final_state=state, coverage=reward,
                    episodes=[dict(coverage=0.0, length=self.length, **{'return': 0.0})] if done[0] else [])
        return obs, state, reward, done, done.copy(), info
