"""Mixture agents: at every reset, pick one of several candidate agents at random and play it."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from gymnasium.utils import seeding

from .base import AgentBase, CameraAgentBase, TargetAgentBase, child_seed

__all__ = ['MixtureCameraAgent', 'MixtureTargetAgent']


class _MixturePolicy:
    """Plays `candidates[k]` for a whole episode, k ~ weights (drawn from the mixture generator).

    Seeding: the agent's generator reseeds every candidate (one child seed each, in order); the
    choice of candidate uses a separate generator seeded with `mixture_seed`. `spawn(n)` gives all
    n clones one shared mixture seed, so teammates play the same candidate in an episode (kept from
    the original).
    """

    def __init__(self, candidates: Sequence[AgentBase], weights=None, mixture_seed: int | None = None,
                 seed: int | None = None) -> None:
        candidates = tuple(candidates)
        if not candidates:
            raise ValueError('a mixture needs at least one candidate agent')
        base = CameraAgentBase if self.TEAM is CameraAgentBase.TEAM else TargetAgentBase
        for candidate in candidates:
            if not isinstance(candidate, base):
                raise TypeError(f'{type(self).__name__} candidates must be {base.__name__} instances, '
                                f'got {candidate!r}')
        weights = np.ones(len(candidates)) if weights is None else np.asarray(weights, dtype=np.float64).ravel()
        if weights.shape != (len(candidates),):
            raise ValueError(f'got {weights.size} weights for {len(candidates)} candidates')
        if not np.all(np.isfinite(weights)) or np.any(weights < 0) or not np.any(weights > 0):
            raise ValueError(f'weights must be finite, non-negative and not all zero, got {weights.tolist()}')
        keep = weights > 0
        self.candidates = tuple(c for c, k in zip(candidates, keep) if k)
        self.weights = weights[keep] / weights[keep].sum()
        self.current_agent = None
        super().__init__(seed=seed)
        self.seed_mixture(mixture_seed)

    def seed(self, seed: int | None = None) -> list[int]:
        """Reseed the agent's generator, then every candidate from it, and restart the generator that
        picks the candidate from its mixture seed (so a reseeded mixture replays its choices); returns
        all seeds used."""
        seeds = super().seed(seed)
        for candidate in self.candidates:
            seeds.append(child_seed(self.np_random))
            candidate.seed(seeds[-1])
        if hasattr(self, 'mixture_seed'):   # not yet during __init__, which seeds the mixture next
            self.seed_mixture(self.mixture_seed)
        return seeds

    def seed_mixture(self, mixture_seed: int | None = None) -> list[int]:
        """Reseed the generator that picks the candidate at each reset (None: fresh entropy, kept as
        `mixture_seed` so that `seed` can restart the same sequence of choices)."""
        self.np_random_mixture, used = seeding.np_random(mixture_seed)
        self.mixture_seed = used
        return [used]

    def clone(self):
        """A new mixture over clones of the candidates, with seed and mixture seed drawn from this one."""
        candidates = [candidate.clone() for candidate in self.candidates]
        seed = child_seed(self.np_random)
        mixture_seed = child_seed(self.np_random)
        return type(self)(candidates, weights=self.weights, mixture_seed=mixture_seed, seed=seed)

    def spawn(self, num_agents: int) -> list:
        clones = [self.clone() for _ in range(num_agents)]
        mixture_seed = child_seed(self.np_random)
        for clone in clones:
            clone.seed_mixture(mixture_seed)
        return clones

    def reset(self, observation) -> None:
        super().reset(observation)
        self.current_agent = self.candidates[int(self.np_random_mixture.choice(len(self.candidates), p=self.weights))]
        self.current_agent.reset(observation)

    def observe(self, observation, info: dict | None = None) -> None:
        self.last_observation = self._accept(observation)
        self.last_info = info
        self.current_agent.observe(observation, info)

    def send_requests(self):
        return self.current_agent.send_requests()

    def receive_requests(self, messages) -> None:
        self.last_requests = messages = tuple(messages)
        self.current_agent.receive_requests(messages)

    def send_responses(self):
        return self.current_agent.send_responses()

    def receive_responses(self, messages) -> None:
        self.last_responses = messages = tuple(messages)
        self.current_agent.receive_responses(messages)

    def act(self, observation, info: dict | None = None, deterministic: bool | None = None):
        self._accept(observation)
        return self.current_agent.act(observation, info, deterministic)

    def __repr__(self) -> str:
        pairs = tuple((float(w), c) for w, c in zip(self.weights, self.candidates))
        return f'{super().__repr__()}{pairs}'

    __str__ = __repr__


class MixtureCameraAgent(_MixturePolicy, CameraAgentBase):
    """A camera agent that plays one of `candidates` per episode, chosen with probabilities `weights`.

    Args:
        candidates: camera agents (each keeps its own state across episodes).
        weights: non-negative weights, one per candidate (default: equal); zero-weight candidates
            are dropped.
        mixture_seed: seed of the generator that picks the candidate.
        seed: seed of the agent's generator (which reseeds the candidates).
    """


class MixtureTargetAgent(_MixturePolicy, TargetAgentBase):
    """A target agent that plays one of `candidates` per episode (arguments as `MixtureCameraAgent`)."""
