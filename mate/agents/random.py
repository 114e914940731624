"""Random agents: a uniform action from the action box, held for `frame_skip` env steps."""

from __future__ import annotations

import numpy as np

from .base import CameraAgentBase, TargetAgentBase

__all__ = ['RandomCameraAgent', 'RandomTargetAgent']


class _RandomPolicy:
    """Draw `action_space`-uniform actions (action space generator) at steps 0, frame_skip, 2 frame_skip, ..."""

    def __init__(self, seed: int | None = None, frame_skip: int = 20) -> None:
        if int(frame_skip) < 1:
            raise ValueError(f'frame_skip must be a positive integer, got {frame_skip!r}')
        self.frame_skip = int(frame_skip)
        self.prev_action = None
        super().__init__(seed=seed)

    def reset(self, observation) -> None:
        super().reset(observation)
        self.prev_action = None

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None) -> np.ndarray:
        self._accept(observation)
        if self.prev_action is None or self.episode_step % self.frame_skip == 0:
            self.prev_action = self._sample_action()
        return self.prev_action.copy()


class RandomCameraAgent(_RandomPolicy, CameraAgentBase):
    """Random rotation and zoom, redrawn every `frame_skip` steps.

    Args:
        seed: seed of the agent's generator.
        frame_skip: number of env steps each drawn action is held (20).
    """


class RandomTargetAgent(_RandomPolicy, TargetAgentBase):
    """Random displacement within the target's step box, redrawn every `frame_skip` steps.

    Args:
        seed: seed of the agent's generator.
        frame_skip: number of env steps each drawn action is held (20).
    """
