"""Cargo transport: generation at reset, warehouse arrival, pick-up, delivery, bounty and rewards.

All functions act on one world row b. `remaining_cargoes[b, src, dst]` counts units waiting at
warehouse src for destination dst; `awaiting_cargo_counts[b, dst]` counts units still owed to dst.
"""

from __future__ import annotations

from ..constants import NUM_WAREHOUSES, WAREHOUSE_RADIUS, WAREHOUSES
from .jit import inline_kernel, kernel
from .perception import is_tracked
from .rng import randint


@kernel
def generate_cargoes(p, w, b):
    """Draw cargo batches of num_cargoes_per_target * Nt random (src != dst) units until every
    warehouse has something to send (whole extra batches, as the original does)."""
    w.remaining_cargoes[b] = 0
    while True:
        for _ in range(p.num_cargoes_per_target * p.num_targets):
            src = randint(w.rng, b, NUM_WAREHOUSES)
            dst = randint(w.rng, b, NUM_WAREHOUSES - 1)
            dst += dst >= src
            w.remaining_cargoes[b, src, dst] += 1
        every_source_busy = True
        for src in range(NUM_WAREHOUSES):
            every_source_busy &= w.remaining_cargoes[b, src].sum() > 0
        if every_source_busy:
            break
    for dst in range(NUM_WAREHOUSES):
        w.awaiting_cargo_counts[b, dst] = w.remaining_cargoes[b, :, dst].sum()


@kernel
def pick_up(p, w, b, t, src):
    """Target t loads cargo at warehouse src if any waits there: a random destination among the
    non-empty ones, min(capacity, waiting) units. Returns whether it loaded."""
    count = 0
    for dst in range(NUM_WAREHOUSES):
        count += w.remaining_cargoes[b, src, dst] > 0
    if count == 0:
        return False
    k = randint(w.rng, b, count)
    for dst in range(NUM_WAREHOUSES):
        if w.remaining_cargoes[b, src, dst] > 0:
            if k == 0:
                load = min(w.target_capacity[b, t], w.remaining_cargoes[b, src, dst])
                w.remaining_cargoes[b, src, dst] -= load
                w.target_goal[b, t] = dst
                w.target_load[b, t] = load
                w.target_freight[b, t] = load * p.freight_scale
                w.target_bounty[b, t] = load * p.bounty_scale
                return True
            k -= 1
    return False


@inline_kernel
def _warehouse_at(w, b, t):
    """Index of the warehouse square containing target t (Chebyshev distance <= 75), or -1."""
    for h in range(NUM_WAREHOUSES):
        dx = abs(w.target_pos[b, t, 0] - WAREHOUSES[h, 0])
        dy = abs(w.target_pos[b, t, 1] - WAREHOUSES[h, 1])
        if max(dx, dy) <= WAREHOUSE_RADIUS:
            return h
    return -1


@inline_kernel
def transport_cargoes(p, w, b):
    """Bounty decay, deliveries and pick-ups of row b after perception.

    Returns the target team's
    (dense, sparse) rewards: dense = -1 per tracked target with bounty left + (freight +
    bounty) per delivery; sparse = freight + 2 bounty - full bounty per delivery. Each target's part of the
    reward (the dense one, or the sparse one with `sparse_reward`) is kept in `target_reward_parts` (they sum to
    the team's): the one place the reward's rule lives, which per-target rewards (`mate.envs.single_team_vector`,
    'own') read.
    """
    dense, sparse = 0.0, 0.0
    for t in range(p.num_targets):
        w.target_reward_parts[b, t] = 0.0
        if w.target_bounty[b, t] > 0 and is_tracked(p, w, b, t):
            dense -= 1.0
            if not p.sparse_reward:
                w.target_reward_parts[b, t] -= 1.0
            w.target_bounty[b, t] -= 1
        w.target_done[b, t] = False
    for t in range(p.num_targets):
        h = _warehouse_at(w, b, t)
        if h < 0:
            continue
        goal = w.target_goal[b, t]
        if goal < 0 or goal == h:
            if goal == h:
                reward = float(w.target_freight[b, t] + w.target_bounty[b, t])
                dense += reward
                paid = reward - (w.target_load[b, t] * p.bounty_scale - w.target_bounty[b, t])
                sparse += paid
                w.target_reward_parts[b, t] += paid if p.sparse_reward else reward
                w.num_delivered_cargoes[b] += w.target_load[b, t]
                w.awaiting_cargo_counts[b, h] -= w.target_load[b, t]
            w.target_freight[b, t] = w.target_bounty[b, t] = 0
            w.target_steps[b, t] = w.target_tracked_steps[b, t] = 0
            w.target_goal[b, t], w.target_load[b, t] = -1, 0
            pick_up(p, w, b, t, h)
            w.target_done[b, t] = goal >= 0
        w.target_empty_bits[b, t, h] = w.remaining_cargoes[b, h].sum() == 0
    return dense, sparse


@kernel
def load_all_targets(p, w, b):
    """Reset option `targets_start_with_cargoes`: each unloaded target takes cargo from the first
    non-empty warehouse in a random order of the four (without moving)."""
    order = 0x3210  # warehouses 0..3 in 4 bits each, order[i] = (order >> 4 i) & 15; shuffled again per target
    for t in range(p.num_targets):
        if w.target_goal[b, t] >= 0:
            continue
        for i in range(NUM_WAREHOUSES - 1, 0, -1):  # Fisher-Yates shuffle
            j = randint(w.rng, b, i + 1)
            swapped = ((order >> (4 * i)) ^ (order >> (4 * j))) & 15  # order[i] ^ order[j]
            order ^= (swapped << (4 * i)) | (swapped << (4 * j))
        for i in range(NUM_WAREHOUSES):
            if pick_up(p, w, b, t, (order >> (4 * i)) & 15):
                break
