"""SingleTarget: one target as a single-agent env; its teammates and all cameras are driven by agents."""

from __future__ import annotations

from mate.messages import Team

from .single_team import SingleTeamSingleAgent

__all__ = ['SingleTarget']


class SingleTarget(SingleTeamSingleAgent):
    """You control one target (slot `env.index`); the other targets are copies of `other_target_agent`, the
    cameras copies of `camera_agent`.

        env = mate.make('MultiAgentTracking-v0', wrappers=[mate.WrapperSpec(
            mate.SingleTarget, other_target_agent=mate.GreedyTargetAgent(seed=0),
            camera_agent=mate.GreedyCameraAgent(seed=0))])
        observation, info = env.reset(seed=0)                        # (D_t,), one dict
        observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

    Spaces: one target's action and observation spaces. Order: as for SingleCamera.
    """

    def __init__(self, env, other_target_agent, camera_agent) -> None:
        super().__init__(env, Team.TARGET, teammate_agent=other_target_agent, opponent_agent=camera_agent)

    @property
    def other_target_agent(self):
        return self.teammate_agent

    @property
    def camera_agent(self):
        return self.opponent_agent
