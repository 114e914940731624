"""MultiTarget: the target team as a multi-agent env, playing against built-in (or any) camera agents."""

from __future__ import annotations

from mate.messages import Team

from .single_team import SingleTeamMultiAgent

__all__ = ['MultiTarget']


class MultiTarget(SingleTeamMultiAgent):
    """All targets are yours; the cameras are copies of `camera_agent` (a `CameraAgentBase`).

        env = mate.make('MultiAgentTracking-v0', wrappers=[
            mate.WrapperSpec(mate.MultiTarget, camera_agent=mate.GreedyCameraAgent(seed=0))])
        target_obs, target_infos = env.reset(seed=0)                 # (Nt, D_t), Nt dicts
        target_obs, reward, terminated, truncated, target_infos = env.step(env.action_space.sample())

    Spaces: `action_space` / `observation_space` are the target joint spaces of the inner env.
    Order: as for MultiCamera.
    """

    def __init__(self, env, camera_agent) -> None:
        super().__init__(env, Team.TARGET, opponent_agent=camera_agent)

    @property
    def camera_agent(self):
        """The prototype of the opponents (seeded, never acts itself)."""
        return self.opponent_agent
