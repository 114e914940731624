"""MultiCamera: the camera team as a multi-agent env, playing against built-in (or any) target agents."""

from __future__ import annotations

from mate.messages import Team

from .single_team import SingleTeamMultiAgent

__all__ = ['MultiCamera']


class MultiCamera(SingleTeamMultiAgent):
    """All cameras are yours; the targets are copies of `target_agent` (a `TargetAgentBase`).

        env = mate.make('MultiAgentTracking-v0', wrappers=[
            mate.WrapperSpec(mate.MultiCamera, target_agent=mate.GreedyTargetAgent(seed=0))])
        camera_obs, camera_infos = env.reset(seed=0)                 # (Nc, D_c), Nc dicts
        camera_obs, reward, terminated, truncated, camera_infos = env.step(env.action_space.sample())

    Spaces: `action_space` / `observation_space` are the camera joint spaces of the inner env.
    Order: before it: observation-mask wrappers, DiscreteCamera/DiscreteTarget, MoreTrainingInformation;
    RepeatedRewardIndividualDone may sit inside or outside.
    """

    def __init__(self, env, target_agent) -> None:
        super().__init__(env, Team.CAMERA, opponent_agent=target_agent)

    @property
    def target_agent(self):
        """The prototype of the opponents (seeded, never acts itself)."""
        return self.opponent_agent
