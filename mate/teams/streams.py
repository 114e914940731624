"""The random streams of a batched team: the generators of `Cls(seed=s_b).spawn(N)` for every row b.

A Python agent has two streams (`mate.agents.base`): its own generator, read through `agent._draw`
(blocks of 128 uniforms, a stack), and its action space's generator, reseeded at every `reset` with a
child seed drawn from its own, read through `agent._space_draw` (blocks of 64). `TeamStreams` keeps
both for every agent (b, i) of B games, as (B, N, C) stacks with (B, N) counts that the compiled rules
(`mate.teams.rules`) take numbers from, and calls each agent's generators exactly when the Python
agent would: so a batched team replays, draw for draw, what the Python agents seeded like its rows do.

Seeds: row b of a team seeded with the integer s gets s + b (as `play_batch` seeds row b of its vector
env); a sequence gives every row its own; None draws fresh entropy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from gymnasium.utils import seeding

__all__ = ['AGENT_BLOCK', 'INT_MAX', 'SPACE_BLOCK', 'TeamStreams', 'UniformDraws', 'child_seed', 'row_seeds',
           'spawned_seeds']

INT_MAX = int(np.iinfo(np.int64).max)
"""Exclusive upper bound of child seeds drawn from an agent's generator."""


def child_seed(generator: np.random.Generator) -> int:
    """A seed for a child generator, drawn from `generator` (one draw)."""
    return int(generator.integers(INT_MAX))


class UniformDraws:
    """Uniform floats in [0, 1) from a numpy Generator, fetched in blocks of `block` numbers.

    Drawing one number from a Generator costs about a microsecond of call overhead; the built-in
    agents draw a few per step, so they take them from a buffer instead. The sequence is fully
    determined by the generator's state when the stream is created.

    The buffer is a stack the compiled rules of `mate.teams.rules` take numbers from too: `values`
    (1, 1, 2 block) float64 holds `left` (1, 1) int64 numbers, the next one on top
    (`values[0, 0, left - 1]`). A new block goes under the numbers left, so they still come first:
    refilling early changes nothing but when the generator is called. The arrays may be views into
    larger (B, N, 2 block) / (B, N) arrays (the streams of a batched team); new ones are made otherwise.
    """

    __slots__ = ('generator', 'block', 'values', 'left')

    def __init__(self, generator: np.random.Generator, block: int = 128, values: np.ndarray | None = None,
                 left: np.ndarray | None = None) -> None:
        self.generator, self.block = generator, block
        self.values = np.empty((1, 1, 2 * block)) if values is None else values
        self.left = np.zeros((1, 1), dtype=np.int64) if left is None else left
        self.left[...] = 0

    def refill(self) -> None:
        """Draw the next block from the generator and put it under the numbers left."""
        block, stack, left = self.block, self.values[0, 0], int(self.left[0, 0])
        if left > block:
            raise RuntimeError(f'a stream refilled with {left} numbers left (at most {block} fit under a new block)')
        stack[block:block + left] = stack[:left]
        stack[:block] = self.generator.random(block)
        self.left[0, 0] = left + block

    def __call__(self) -> float:
        left = self.left
        if left[0, 0] == 0:
            self.refill()
        left[0, 0] -= 1
        return float(self.values[0, 0, left[0, 0]])


AGENT_BLOCK = 128
"""Uniforms fetched at once from an agent's own generator (as `AgentBase` does)."""
SPACE_BLOCK = 64
"""Uniforms fetched at once from an agent's action-space generator (as `AgentBase` does)."""


def row_seeds(seed: int | Sequence[int] | None, num_envs: int) -> list[int]:
    """The seed of every row: s + b for an integer s, the B given integers, or fresh entropy for None.
    ValueError (one line) for a sequence of another length or a negative seed."""
    if seed is None:
        base = int(np.random.SeedSequence().entropy) >> 64
        seeds = [base + b for b in range(num_envs)]
    elif np.ndim(seed) == 0:
        seeds = [int(seed) + b for b in range(num_envs)]
    else:
        seeds = [int(s) for s in seed]
        if len(seeds) != num_envs:
            raise ValueError(f'seed must be one integer or {num_envs} integers (one per row), got {len(seeds)}')
    if min(seeds) < 0:
        raise ValueError(f'seeds must be non-negative integers, got {min(seeds)}')
    return seeds


def spawned_seeds(seed: int, count: int) -> list[int]:
    """The seeds of `Cls(seed=seed).spawn(count)`: the prototype's generator, then one child seed each."""
    prototype, _ = seeding.np_random(seed)
    return [child_seed(prototype) for _ in range(count)]


class TeamStreams:
    """The two random streams of every agent of B games of N agents.

    `draws` (B, N, 2 x 128) / `left` (B, N): the agents' own streams; `space` (B, N, 2 x 64) /
    `space_left` (B, N): their action spaces' streams, empty until the agent's first `reset`.

    Args:
        seeds: the seed of every row (`row_seeds`); agent i of row b plays with the i-th seed of
            `spawned_seeds(seeds[b], num_agents)`.
        num_agents: N.
    """

    def __init__(self, seeds: Sequence[int], num_agents: int) -> None:
        num_envs = len(seeds)
        self.shape = (num_envs, num_agents)
        self.draws = np.zeros((num_envs, num_agents, 2 * AGENT_BLOCK))
        self.left = np.zeros((num_envs, num_agents), dtype=np.int64)
        self.space = np.zeros((num_envs, num_agents, 2 * SPACE_BLOCK))
        self.space_left = np.zeros((num_envs, num_agents), dtype=np.int64)
        self._own = [[UniformDraws(seeding.np_random(agent_seed)[0], AGENT_BLOCK, self.draws[b:b + 1, i:i + 1],
                                   self.left[b:b + 1, i:i + 1])
                      for i, agent_seed in enumerate(spawned_seeds(row_seed, num_agents))]
                     for b, row_seed in enumerate(seeds)]
        self._spaces = [[None] * num_agents for _ in range(num_envs)]

    def reset(self, rows: np.ndarray) -> None:
        """The agents of the rows `rows` (B,) bool start an episode: each reseeds its action space with a
        child seed drawn from its own generator (its own stack is kept, as a Python agent's is)."""
        for b in np.flatnonzero(rows).tolist():
            own, spaces = self._own[b], self._spaces[b]
            for i in range(self.shape[1]):
                generator, _ = seeding.np_random(child_seed(own[i].generator))
                spaces[i] = UniformDraws(generator, SPACE_BLOCK, self.space[b:b + 1, i:i + 1],
                                         self.space_left[b:b + 1, i:i + 1])

    def refill(self, agents: np.ndarray) -> None:
        """Put the next block of their own generators under the stacks of the agents `agents` (B, N) bool."""
        for b, i in zip(*np.nonzero(agents)):
            self._own[b][i].refill()

    def top_up_space(self, rows: np.ndarray, count: int = 2) -> None:
        """Make sure the action-space stack of every agent of the rows `rows` holds `count` numbers."""
        for b, i in zip(*np.nonzero(rows[:, None] & (self.space_left < count))):
            self._spaces[b][i].refill()

    def generator(self, b: int, i: int) -> np.random.Generator:
        """Agent (b, i)'s own generator."""
        return self._own[b][i].generator

    def space_generator(self, b: int, i: int) -> np.random.Generator | None:
        """Agent (b, i)'s action-space generator (None before its first reset)."""
        space = self._spaces[b][i]
        return None if space is None else space.generator

    def state_dict(self) -> dict:
        """The streams as plain data: the stacks and every generator's state (a training run's exact resume)."""
        return dict(draws=self.draws.copy(), left=self.left.copy(), space=self.space.copy(),
                    space_left=self.space_left.copy(),
                    own=[[draw.generator.bit_generator.state for draw in row] for row in self._own],
                    spaces=[[None if draw is None else draw.generator.bit_generator.state for draw in row]
                            for row in self._spaces])

    def load_state_dict(self, state: dict) -> None:
        """Continue from `state_dict()`'s output (taken from streams of the same shape)."""
        for name in ('draws', 'left', 'space', 'space_left'):
            getattr(self, name)[...] = state[name]     # in place: the agents' stacks are views of these
        for row, states in zip(self._own, state['own']):
            for draw, generator_state in zip(row, states):
                draw.generator.bit_generator.state = generator_state
        for b, states in enumerate(state['spaces']):
            for i, generator_state in enumerate(states):
                if generator_state is None:
                    self._spaces[b][i] = None
                    continue
                generator = np.random.Generator(np.random.PCG64())
                generator.bit_generator.state = generator_state
                left = self.space_left[b:b + 1, i:i + 1]
                kept = int(left[0, 0])
                self._spaces[b][i] = UniformDraws(generator, SPACE_BLOCK, self.space[b:b + 1, i:i + 1], left)
                left[0, 0] = kept      # (a new UniformDraws empties its stack)
