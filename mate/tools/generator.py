"""Configuration generator: a preset-like YAML file for any numbers of cameras, targets and obstacles.

Cameras are placed to cover the terrain: their positions minimise the largest distance from
any terrain point to its nearest camera (the k-centre problem), by Adam on a smoothed
objective over a 101 x 101 mesh of the normalised square [-1, 1]^2, with small penalties
that keep cameras apart and off the border. The sight range is then twice the achieved
covering distance. Lengths in the file are world units (the terrain is [-1000, 1000]^2).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ..config import read_config
from ..constants import TERRAIN_SIZE

MESH_POINTS = 101
RESTARTS = 3
"""Optimisations from different starts; the best placement is kept."""
ITERATIONS = 2000
"""Adam steps per optimisation at most (it stops earlier once the learning rate has decayed)."""
GENERATION_SECONDS = '10-25'
"""Wall time of a placement of 6 cameras on our 2-core machines, quiet to busy (docs/environment/configs.md)."""
CAMERA_RANGE_HALF_WIDTH = 0.02 * TERRAIN_SIZE  # each camera's spawn box is its point +-20
TARGET_RANGE = [-500.0, 500.0, -500.0, 500.0]
OBSTACLE_RANGE = [-TERRAIN_SIZE, TERRAIN_SIZE, -TERRAIN_SIZE, TERRAIN_SIZE]


@dataclass
class Placement:
    points: np.ndarray      # (C, 2) camera positions in world units
    covering_distance: float  # largest distance from a terrain point to its nearest camera (world units)
    iterations: int


def _mesh() -> np.ndarray:
    axis = np.linspace(-1.0, 1.0, MESH_POINTS)
    return np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2)


def _softmax(x: np.ndarray, axis: int) -> np.ndarray:
    z = np.exp(x - x.max(axis=axis, keepdims=True))
    return z / z.sum(axis=axis, keepdims=True)


def _objective_gradient(u: np.ndarray, mesh: np.ndarray, sharpness: float = 200.0):
    """Smoothed max over mesh points of the soft-min distance to the cameras, its gradient
    (C, 2), and the exact covering distance (all in normalised units)."""
    delta = u[None, :, :] - mesh[:, None, :]                       # (M, C, 2)
    dist = np.sqrt((delta ** 2).sum(-1) + 1e-12)                    # (M, C)
    nearest_weights = _softmax(-sharpness * dist, axis=1)            # soft arg-min over cameras
    nearest = (nearest_weights * dist).sum(axis=1)                   # (M,)
    worst_weights = _softmax(sharpness * nearest, axis=0)            # soft arg-max over points
    grad = ((worst_weights[:, None] * nearest_weights)[:, :, None] * delta / dist[:, :, None]).sum(axis=0)
    exact = float(dist.min(axis=1).max())
    return float((worst_weights * nearest).sum()), grad, exact


def _penalty_gradient(u: np.ndarray, apart: float = 1e-3, border: float = 1e-2) -> np.ndarray:
    """Gradient of small penalties: cameras closer than 0.2 to each other, or beyond 0.9 of the border."""
    grad = np.zeros_like(u)
    delta = u[:, None, :] - u[None, :, :]
    dist = np.sqrt((delta ** 2).sum(-1) + 1e-12)
    close = (dist < 0.2) & ~np.eye(len(u), dtype=bool)
    grad -= apart * (close[:, :, None] * delta / dist[:, :, None]).sum(axis=1)
    outside = np.abs(u) - 0.9
    grad += border * 2.0 * np.maximum(outside, 0.0) * np.sign(u)
    return grad


def _farthest_point_start(num_cameras: int, mesh: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Greedy k-centre start (each new camera at the mesh point farthest from the others)."""
    points = [mesh[rng.integers(len(mesh))]]
    nearest = np.linalg.norm(mesh - points[0], axis=1)
    for _ in range(num_cameras - 1):
        points.append(mesh[np.argmax(nearest)])
        nearest = np.minimum(nearest, np.linalg.norm(mesh - points[-1], axis=1))
    return 0.9 * np.array(points)


def place_cameras(num_cameras: int, seed: int = 0, restarts: int = RESTARTS, progress=None, **adam) -> Placement:
    """Camera positions covering the terrain: the best of `restarts` optimisations. `progress(restart, iteration,
    covering_distance)` (world units) is called every 50 Adam steps and when an optimisation ends."""
    rng = np.random.default_rng(seed)
    mesh = _mesh()
    runs = []
    for restart in range(restarts):
        report = None if progress is None else lambda it, best, r=restart: progress(r, it, best * TERRAIN_SIZE)
        runs.append(_optimise(_farthest_point_start(num_cameras, mesh, rng), mesh, progress=report, **adam))
    return min(runs, key=lambda run: run.covering_distance)


def _optimise(u: np.ndarray, mesh: np.ndarray, iterations: int = ITERATIONS, lr: float = 1e-2,
              patience: int = 100, progress=None) -> Placement:
    """Adam with a plateau learning-rate schedule (halve after `patience` steps without progress);
    `progress(iteration, best covering distance in normalised units)` every 50 steps and at the end."""
    m, v = np.zeros_like(u), np.zeros_like(u)
    best, best_u, stale = np.inf, u.copy(), 0
    for it in range(1, iterations + 1):
        _, grad, exact = _objective_gradient(u, mesh)
        grad = grad + _penalty_gradient(u)
        if exact < best - 1e-6:
            best, best_u, stale = exact, u.copy(), 0
        else:
            stale += 1
            if stale >= patience:
                lr, stale = lr * 0.5, 0
                if lr < 1e-5:
                    break
        if progress is not None and it % 50 == 0:
            progress(it, best)
        m = 0.9 * m + 0.1 * grad
        v = 0.999 * v + 0.001 * grad ** 2
        u = np.clip(u - lr * (m / (1 - 0.9 ** it)) / (np.sqrt(v / (1 - 0.999 ** it)) + 1e-8), -1.0, 1.0)
    if progress is not None:
        progress(iterations, best)   # done (possibly early): the whole share of this optimisation
    return Placement(points=best_u * TERRAIN_SIZE, covering_distance=best * TERRAIN_SIZE, iterations=it)


def generate_config(num_cameras: int = 4, num_targets: int = 8, num_obstacles: int = 0,
                    num_cargoes_per_target: int = 8, obstacle_transmittance: float = 0.1, seed: int = 0,
                    restarts: int = RESTARTS, progress=None) -> dict:
    """A validated configuration dict built from the default preset (see module docstring); `progress`: as
    `place_cameras`'s (the placement takes GENERATION_SECONDS seconds)."""
    for name, value, low in (('num_cameras', num_cameras, 0), ('num_targets', num_targets, 1),
                             ('num_obstacles', num_obstacles, 0),
                             ('num_cargoes_per_target', num_cargoes_per_target, 4)):
        if not isinstance(value, (int, np.integer)) or value < low:
            raise ValueError(f'{name} must be an integer >= {low}, got {value!r}')
    config = read_config('MATE-4v8-9')
    config['name'] = f'MultiAgentTracking({num_cameras}v{num_targets}, {num_obstacles})'
    config['num_cargoes_per_target'] = int(num_cargoes_per_target)
    covering = TERRAIN_SIZE * np.sqrt(2.0)
    if num_cameras > 0:
        placement = place_cameras(num_cameras, seed, restarts, progress=progress)
        covering = placement.covering_distance
        sight = 2.0 * covering
        w = CAMERA_RANGE_HALF_WIDTH
        config['camera']['location'] = []
        config['camera']['location_random_range'] = [
            [round(x - w, 3), round(x + w, 3), round(y - w, 3), round(y + w, 3)] for x, y in placement.points.tolist()]
        config['camera']['max_sight_range'] = round(sight, 3)
        config['camera']['radius'] = round(min(40.0, 0.1 * sight), 3)
    else:
        del config['camera']
    config['target']['location'] = []
    config['target']['location_random_range'] = [list(TARGET_RANGE) for _ in range(num_targets)]
    config['target']['sight_range'] = round(config.get('camera', {}).get('max_sight_range', 2 * covering) / 2, 3)
    if num_obstacles > 0:
        low, high = config['obstacle']['radius_random_range']
        config['obstacle']['location'] = []
        config['obstacle']['location_random_range'] = [list(OBSTACLE_RANGE) for _ in range(num_obstacles)]
        config['obstacle']['radius_random_range'] = [low, round(min(max(3 * low, 0.15 * covering), high), 3)]
        config['obstacle']['transmittance'] = float(min(max(obstacle_transmittance, 0.0), 1.0))
    else:
        del config['obstacle']
    return read_config(config)


def check_config_path(path: str | Path) -> Path:
    """`path` as a Path; ValueError unless it names a YAML file (.yaml or .yml)."""
    path = Path(path)
    if path.suffix.lower() not in ('.yaml', '.yml'):
        raise ValueError(f'config path must end in .yaml or .yml, got {str(path)!r}')
    return path


def write_config(config: dict, path: str | Path) -> Path:
    """Write a configuration as YAML (with a comment saying where it came from)."""
    path = check_config_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = yaml.safe_dump(config, sort_keys=False, default_flow_style=None)
    path.write_text(f'# Generated by `mate generate-config`: {config["name"]}\n{text}')
    return path


def plot_config(config: dict, path: str | Path) -> Path:
    """Save a PNG of the camera placement with each camera's reach (needs matplotlib)."""
    try:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
    except ImportError:
        raise ImportError('--plot needs matplotlib: pip install matplotlib') from None
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.add_patch(plt.Rectangle((-TERRAIN_SIZE, -TERRAIN_SIZE), 2 * TERRAIN_SIZE, 2 * TERRAIN_SIZE, fill=False))
    camera = config.get('camera', {})
    for x_low, x_high, y_low, y_high in camera.get('location_random_range', []):
        centre = ((x_low + x_high) / 2, (y_low + y_high) / 2)
        ax.add_patch(plt.Circle(centre, camera['max_sight_range'] / 2, alpha=0.15))
        ax.plot(*centre, 'o', color='navy')
    ax.set_xlim(-1100, 1100)
    ax.set_ylim(-1100, 1100)
    ax.set_aspect('equal')
    ax.set_title(config['name'])
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)
