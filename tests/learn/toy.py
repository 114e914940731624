"""A trivial batched task for the learner: every agent sees a one-hot cue and is paid for matching it."""

import numpy as np


class CueMatching:
    """B envs x N agents; obs = one-hot of a random cue among A actions; team reward = fraction of agents
    whose action equals their cue; episodes of `length` decisions (the last one is a truncation)."""

    team = 'camera'
    frame_skip = 1

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



class OwnCueMatching(CueMatching):
    """CueMatching with each agent paid for its own match only: rewards (B, N), as `TeamVecEnv` gives
    them with `credit='difference'`."""

    credit = 'difference'

    def step(self, actions):
        own = (np.asarray(actions) == self.cue).astype(np.float64)      # before the next cue is drawn
        obs, state, _, done, truncated, info = super().step(actions)
        return obs, state, own, done, truncated, info
