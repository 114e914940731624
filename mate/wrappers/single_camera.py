"""SingleCamera: one camera as a single-agent env; its teammates and all targets are driven by agents."""

from __future__ import annotations

from mate.messages import Team

from .single_team import SingleTeamSingleAgent

__all__ = ['SingleCamera']


class SingleCamera(SingleTeamSingleAgent):
    """You control one camera (slot `env.index`); the other cameras are copies of `other_camera_agent`, the
    targets copies of `target_agent`.

        env = mate.make('MultiAgentTracking-v0', wrappers=[mate.WrapperSpec(
            mate.SingleCamera, other_camera_agent=mate.GreedyCameraAgent(seed=0),
            target_agent=mate.GreedyTargetAgent(seed=0))])
        observation, info = env.reset(seed=0)                        # (D_c,), one dict
        observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

    Spaces: one camera's action and observation spaces. Order: as for MultiCamera, and nothing that needs
    every agent's reward (RepeatedRewardIndividualDone, Auxiliary*Rewards) may follow it.
    """

    def __init__(self, env, other_camera_agent, target_agent) -> None:
        super().__init__(env, Team.CAMERA, teammate_agent=other_camera_agent, opponent_agent=target_agent)

    @property
    def other_camera_agent(self):
        return self.teammate_agent

    @property
    def target_agent(self):
        return self.opponent_agent
