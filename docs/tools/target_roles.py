"""What each target does, per agent index over episodes, and whether the team splits into distinct roles.

    python docs/tools/target_roles.py --target-agent checkpoint:RUN/final.pt [--config MATE-4v8-0] [--episodes 20]
                                   [--camera-agent greedy] [--json OUT] [--gif PATH]

Plays E episodes (episode i: seed i, as `mate evaluate`) of a target policy (`checkpoint:PATH`, `pretrained:NAME`
or a rule-based name such as `greedy`) against greedy cameras, the single agents talking through the env's channel
(`mate.group_step`), and measures per target index and episode (FEATURES below). Then the role analysis: the
per-index means, standardised over the targets, are clustered by k-means (k = 2 and 3, k-means++ starts from a
seeded numpy generator, the k of the larger mean silhouette kept); clusters count as distinct roles only when the
silhouette is at least `MIN_SILHOUETTE` and every pair of clusters differs in some feature by at least
`MIN_SEPARATION` within-cluster standard deviations (of the per-episode values). Plain-words labels come from
the features that set a distinct cluster apart, never from its index. Prints markdown tables; `--json OUT` writes
everything, `--gif PATH` records the first episode with the messages drawn (`RenderCommunication(kinds=True)`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

import mate
from mate.constants import WAREHOUSE_RADIUS, WAREHOUSES
from mate.cli.main import ArgumentParser
from mate.evaluation.evaluate import FrameRecorder, play_episode, resolve_agent
from mate.messages import Team

FEATURES = {
    'tracked': 'share of steps the target is seen by some camera',
    'occluded': 'share of steps it is unseen, inside some camera\'s sector, and every such camera\'s line of sight '
                'to it crosses an obstacle (0 on configs without obstacles)',
    'camera_distance': 'mean distance to the nearest camera centre (world units)',
    'deliveries': 'deliveries (trips that reached their destination warehouse) per episode',
    'delivered_units': 'cargo units delivered per episode',
    'loaded': 'share of steps carrying cargo',
    'requests_sent': 'requests (peer-to-peer messages of the request round) sent per decision',
    'requests_received': 'requests received from teammates per decision',
    'replies_sent': 'replies (peer-to-peer messages of the response round) sent per decision',
    'replies_received': 'replies received per decision',
    'broadcasts_sent': 'broadcasts sent per decision',
    'broadcasts_received': 'teammates\' broadcasts received per decision',
}
NAMES = tuple(FEATURES)
MIN_SILHOUETTE = 0.5
"""Mean silhouette from which a clustering counts as structure (Kaufman and Rousseeuw's 'reasonable')."""
MIN_SEPARATION = 2.0
"""Between-cluster difference of a feature, in pooled within-cluster standard deviations, that tells two roles apart."""
WORDS = {'tracked': ('tracked often', 'rarely tracked'),
         'occluded': ('often behind obstacles', 'rarely behind obstacles'),
         'camera_distance': ('far from cameras', 'near cameras'), 'deliveries': ('most deliveries', 'few deliveries'),
         'loaded': ('often loaded', 'rarely loaded'), 'requests_sent': ('asks often', 'asks rarely'),
         'requests_received': ('asked often', 'asked rarely'),
         'broadcasts_sent': ('broadcasts often', 'broadcasts rarely')}
"""Words for a cluster whose feature lies MIN_SEPARATION within-cluster std above (first) or below the others."""


# --------------------------------------------------------------------------- measuring

def segment_hits_disc(start: np.ndarray, end: np.ndarray, discs: np.ndarray) -> np.ndarray:
    """Whether the segments start (..., 2) -> end (..., 2) cross any disc of `discs` (M, 3) [x, y, r]: (...,) bool."""
    if not len(discs):
        return np.zeros(np.broadcast_shapes(start.shape, end.shape)[:-1], dtype=bool)
    d = (end - start)[..., None, :]                                           # (..., 1, 2)
    rel = discs[:, :2] - start[..., None, :]                                  # (..., M, 2)
    s = np.clip((rel * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-12), 0.0, 1.0)
    closest = s[..., None] * d - rel
    return ((closest ** 2).sum(-1) < discs[:, 2] ** 2).any(-1)


def occluded(world: dict) -> np.ndarray:
    """(Nt,) bool: seen by no camera, inside some camera's sector (range and angle), and hidden from every such
    camera by an obstacle on the segment between them."""
    cameras = np.asarray(world['camera_state'], dtype=np.float64).reshape(-1, 9)[:, :2]
    targets = np.asarray(world['target_state'], dtype=np.float64).reshape(-1, 14)[:, :2]
    seen = np.asarray(world['camera_target_view_mask'], dtype=bool).reshape(len(cameras), -1).any(0)
    rel = targets[None] - cameras[:, None]                                    # (Nc, Nt, 2)
    dist = np.hypot(rel[..., 0], rel[..., 1])
    bearing = np.degrees(np.arctan2(rel[..., 1], rel[..., 0]))
    off = (bearing - np.asarray(world['camera_orientation'])[:, None] + 180.0) % 360.0 - 180.0
    in_sector = ((dist <= np.asarray(world['camera_sight_range'])[:, None])
                 & (np.abs(off) <= 0.5 * np.asarray(world['camera_viewing_angle'])[:, None]))
    blocked = segment_hits_disc(np.broadcast_to(cameras[:, None], rel.shape), np.broadcast_to(targets[None], rel.shape),
                                np.asarray(world['obstacle_state'], dtype=np.float64).reshape(-1, 3))
    return ~seen & in_sector.any(0) & np.where(in_sector, blocked, True).all(0)


def at_warehouse(positions: np.ndarray) -> np.ndarray:
    """(Nt,) index of the warehouse square each position lies in (Chebyshev distance <= WAREHOUSE_RADIUS), or -1."""
    inside = np.abs(positions[:, None] - np.asarray(WAREHOUSES)[None]).max(-1) <= WAREHOUSE_RADIUS
    return np.where(inside.any(1), inside.argmax(1), -1)


class EpisodeRecorder:
    """`play_episode`'s `on_step`: sums the per-target quantities of every step of one episode (world after the
    step, messages of the step from the `RenderCommunication` wrapper around the env)."""

    def __init__(self, frame_skip: int, then=None) -> None:
        self.frame_skip, self.then = frame_skip, then
        self.sums, self.steps, self.previous = None, 0, None

    def __call__(self, env, step: int, joint_action) -> None:
        if self.then is not None:
            self.then(env, step, joint_action)
        base = env.unwrapped
        world = base.get_world()
        if step > 0:
            nt = base.num_targets
            if self.sums is None:
                self.sums = {name: np.zeros(nt) for name in NAMES}
            s = self.sums
            cameras = np.asarray(world['camera_state']).reshape(-1, 9)[:, :2]
            positions = np.asarray(world['target_state']).reshape(-1, 14)[:, :2]
            s['tracked'] += np.asarray(world['camera_target_view_mask'], dtype=bool).reshape(-1, nt).any(0)
            s['occluded'] += occluded(world)
            if len(cameras):
                s['camera_distance'] += np.hypot(*(positions[:, None] - cameras[None]).transpose(2, 0, 1)).min(1)
            goal = np.asarray(self.previous['target_goal'])
            delivered = (goal >= 0) & (at_warehouse(positions) == goal)
            s['deliveries'] += delivered
            s['delivered_units'] += delivered * np.asarray(self.previous['target_freight']) / base.params.freight_scale
            s['loaded'] += np.asarray(world['target_goal']) >= 0
            sent, received = env.sent[Team.TARGET], env.received[Team.TARGET]
            for kind, plural in (('request', 'requests'), ('reply', 'replies'), ('broadcast', 'broadcasts')):
                s[f'{plural}_sent'] += sent[kind]
                s[f'{plural}_received'] += received[kind].sum(0)
            self.steps = step
        self.previous = world

    def features(self) -> np.ndarray:
        """(Nt, F) this episode's features in `NAMES` order."""
        steps, decisions = max(self.steps, 1), max(self.steps / self.frame_skip, 1e-9)
        out = []
        for name in NAMES:
            total = self.sums[name]
            if name in ('deliveries', 'delivered_units'):
                out.append(total)
            elif name.endswith(('_sent', '_received')):
                out.append(total / decisions)
            else:
                out.append(total / steps)
        return np.stack(out, axis=1)


def play(config: str, target_agent: str, camera_agent: str = 'greedy', episodes: int = 20, seed: int = 0,
         max_steps: int = 2000, recorder: FrameRecorder | None = None) -> np.ndarray:
    """(E, Nt, F) features of E episodes (episode i: seed + i); `recorder` records the first one. ValueError for
    an unknown agent (and CheckpointError for a bad checkpoint)."""
    target_cls = resolve_agent(target_agent, Team.TARGET)
    camera_cls = resolve_agent(camera_agent, Team.CAMERA)
    env = mate.RenderCommunication(mate.make('MultiAgentTracking-v0', config=config), duration=1, kinds=True)
    frame_skip = int(getattr(target_cls(seed=seed), 'frame_skip', 1))
    rows = []
    for episode in range(episodes):
        log = EpisodeRecorder(frame_skip, recorder if episode == 0 else None)
        play_episode(env, lambda seed: camera_cls(seed=seed), lambda seed: target_cls(seed=seed), seed + episode,
                     max_steps, log)
        rows.append(log.features())
    return np.stack(rows)


# --------------------------------------------------------------------------- roles

def kmeans(x: np.ndarray, k: int, rng: np.random.Generator, restarts: int = 20, iterations: int = 100) -> np.ndarray:
    """Labels (N,) of the best of `restarts` k-means runs (k-means++ starts) on points x (N, D)."""
    best, best_inertia = None, np.inf
    for _ in range(restarts):
        centres = [x[rng.integers(len(x))]]
        for _ in range(1, k):
            d2 = ((x[:, None] - np.array(centres)[None]) ** 2).sum(-1).min(1)
            p = d2 / d2.sum() if d2.sum() > 0 else np.full(len(x), 1.0 / len(x))
            centres.append(x[rng.choice(len(x), p=p)])
        centres = np.array(centres)
        for _ in range(iterations):
            labels = ((x[:, None] - centres[None]) ** 2).sum(-1).argmin(1)
            moved = np.array([x[labels == j].mean(0) if (labels == j).any() else centres[j] for j in range(k)])
            if np.allclose(moved, centres):
                break
            centres = moved
        inertia = ((x - centres[labels]) ** 2).sum()
        if len(np.unique(labels)) == k and inertia < best_inertia - 1e-12:
            best, best_inertia = labels, inertia
    return best


def silhouette(x: np.ndarray, labels: np.ndarray) -> float:
    """Mean silhouette of a clustering (points alone in their cluster score 0)."""
    d = np.sqrt(((x[:, None] - x[None]) ** 2).sum(-1))
    scores = []
    for i, label in enumerate(labels):
        own = labels == label
        if own.sum() == 1:
            scores.append(0.0)
            continue
        a = d[i, own].sum() / (own.sum() - 1)
        b = min(d[i, labels == other].mean() for other in np.unique(labels) if other != label)
        scores.append((b - a) / max(a, b) if max(a, b) > 0 else 0.0)
    return float(np.mean(scores))


def separation(per_episode: np.ndarray, labels: np.ndarray, a: int, b: int) -> np.ndarray:
    """(F,) |mean_a - mean_b| / pooled within-cluster std of the per-episode values (E, Nt, F); inf where the
    pooled std is 0 and the means differ, 0 where both are 0."""
    xa = per_episode[:, labels == a].reshape(-1, per_episode.shape[-1])
    xb = per_episode[:, labels == b].reshape(-1, per_episode.shape[-1])
    pooled = np.sqrt(0.5 * (xa.var(0) + xb.var(0)))
    gap = np.abs(xa.mean(0) - xb.mean(0))
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(pooled > 0, gap / np.where(pooled > 0, pooled, 1.0), np.where(gap > 1e-12, np.inf, 0.0))


def roles(per_episode: np.ndarray, seed: int = 0, names: tuple[str, ...] = NAMES) -> dict:
    """The role analysis of per-episode features (E, Nt, F), as described in the module docstring."""
    means = per_episode.mean(0)                                             # (Nt, F)
    std = means.std(0)
    used = std > 1e-12
    result = {'features_used': [n for n, u in zip(names, used) if u], 'distinct': False, 'clusters': [], 'k': None,
              'silhouette': None, 'min_pair_separation': None, 'verdict': ''}
    nt = len(means)
    if not used.any() or nt < 3:
        result['verdict'] = 'no distinct roles: the targets do not differ in any feature' if nt >= 3 else \
            'no role analysis: fewer than 3 targets'
        return result
    z = (means[:, used] - means[:, used].mean(0)) / std[used]
    rng = np.random.default_rng(seed)
    best = None
    for k in range(2, min(3, nt - 1) + 1):
        labels = kmeans(z, k, rng)
        if labels is None:
            continue
        score = silhouette(z, labels)
        if best is None or score > best[1]:
            best = (labels, score)
    labels, score = best
    k = len(np.unique(labels))
    pairs = {(a, b): separation(per_episode, labels, a, b) for a in range(k) for b in range(a + 1, k)}
    min_pair = min(float(s[used].max()) for s in pairs.values())
    distinct = score >= MIN_SILHOUETTE and min_pair >= MIN_SEPARATION
    result.update(k=k, silhouette=score, min_pair_separation=min_pair, distinct=bool(distinct))
    for c in range(k):
        members = np.flatnonzero(labels == c)
        others = per_episode[:, labels != c].reshape(-1, per_episode.shape[-1])
        own = per_episode[:, labels == c].reshape(-1, per_episode.shape[-1])
        pooled = np.sqrt(0.5 * (own.var(0) + others.var(0)))
        with np.errstate(divide='ignore', invalid='ignore'):
            signed = np.where(pooled > 0, (own.mean(0) - others.mean(0)) / np.where(pooled > 0, pooled, 1.0), 0.0)
        words = [WORDS[n][0 if signed[i] > 0 else 1] for i, n in enumerate(names)
                 if used[i] and n in WORDS and abs(signed[i]) >= MIN_SEPARATION] if distinct else []
        label = ''
        if distinct:
            t, d = names.index('tracked'), names.index('deliveries')
            if signed[t] >= MIN_SEPARATION and signed[d] <= -MIN_SEPARATION:
                label = 'distractor-like'
            elif signed[t] <= -MIN_SEPARATION and signed[d] >= MIN_SEPARATION:
                label = 'running-back-like'
        result['clusters'].append({'cluster': c, 'targets': members.tolist(),
                                   'means': dict(zip(names, own.mean(0).tolist())),
                                   'difference_from_rest': dict(zip(names, signed.tolist())),
                                   'description': ', '.join(words), 'label': label})
    if distinct:
        result['verdict'] = (f'{k} distinct roles (silhouette {score:.2f} >= {MIN_SILHOUETTE}, every pair of clusters '
                             f'differs by >= {min_pair:.1f} within-cluster std in some feature)')
    else:
        result['verdict'] = (f'no distinct roles: best k = {k} has silhouette {score:.2f} (needs >= {MIN_SILHOUETTE}) '
                             f'and its two closest clusters differ by at most {min_pair:.1f} within-cluster std in '
                             f'any feature (needs >= {MIN_SEPARATION})')
    return result


# --------------------------------------------------------------------------- report

def markdown(per_episode: np.ndarray, analysis: dict) -> str:
    means, stds = per_episode.mean(0), per_episode.std(0)
    head = '| target | ' + ' | '.join(NAMES) + ' |'
    lines = [head, '|' + '---|' * (len(NAMES) + 1)]
    for t in range(len(means)):
        lines.append(f'| {t} | ' + ' | '.join(f'{m:.3g} ± {s:.2g}' for m, s in zip(means[t], stds[t])) + ' |')
    lines += ['', f"Roles: {analysis['verdict']}."]
    if analysis['clusters']:
        lines += ['', '| cluster | targets | ' + ' | '.join(NAMES) + ' | description |',
                  '|' + '---|' * (len(NAMES) + 3)]
        for c in analysis['clusters']:
            words = ', '.join(w for w in (c['description'], c['label'] and f"~ {c['label']}") if w) or '-'
            lines.append(f"| {c['cluster']} | {' '.join(map(str, c['targets']))} | "
                         + ' | '.join(f"{c['means'][n]:.3g}" for n in NAMES) + f' | {words} |')
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog='target_roles.py', description=__doc__.splitlines()[0])
    parser.add_argument('--target-agent', default='greedy',
                        help='checkpoint:PATH, pretrained:NAME or a rule-based name (default greedy)')
    parser.add_argument('--camera-agent', default='greedy', help='default greedy')
    parser.add_argument('--config', default='MATE-4v8-0', help='preset or YAML/JSON path (default MATE-4v8-0)')
    parser.add_argument('--episodes', type=int, default=20, help='episodes, seeds seed..seed+E-1 (default 20)')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--max-episode-steps', type=int, default=2000)
    parser.add_argument('--json', default=None, metavar='OUT', help='write the features and the analysis')
    parser.add_argument('--gif', default=None, metavar='PATH', help='record the first episode with the messages drawn')
    parser.add_argument('--frame-size', type=int, default=600)
    parser.add_argument('--frame-every', type=int, default=4)
    args = parser.parse_args(argv)
    for flag in ('episodes', 'max_episode_steps', 'frame_size', 'frame_every'):
        if getattr(args, flag) < 1:
            parser.error(f"--{flag.replace('_', '-')} must be at least 1, got {getattr(args, flag)}")
    if args.gif is not None and not args.gif.lower().endswith('.gif'):
        parser.error(f'--gif {args.gif!r}: the path must end with .gif')
    recorder = None if args.gif is None else FrameRecorder(args.frame_size, args.frame_every,
                                                           max_episode_steps=args.max_episode_steps)
    try:
        per_episode = play(args.config, args.target_agent, args.camera_agent, args.episodes, args.seed,
                           args.max_episode_steps, recorder)
    except Exception as exc:   # unknown agent, bad checkpoint, bad config: one line
        if type(exc).__name__ not in ('ValueError', 'CheckpointError', 'ConfigError', 'FileNotFoundError'):
            raise
        print(f'{parser.prog}: error: {exc}', file=sys.stderr)
        return 2
    analysis = roles(per_episode, seed=args.seed)
    print(f'{args.target_agent} targets vs {args.camera_agent} cameras on {args.config}, {args.episodes} episodes '
          f'(seeds {args.seed}..{args.seed + args.episodes - 1}); per target index: mean ± std over episodes\n')
    print(markdown(per_episode, analysis))
    if recorder is not None:
        from mate.tools.video import save_gif
        recorder.close()
        print(f'\nfirst episode ({len(recorder.frames)} frames) saved to '
              f'{save_gif(recorder.frames, args.gif, fps=max(1, round(30 / args.frame_every)))}')
    if args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({'settings': vars(args), 'features': FEATURES,
                                   'per_episode': per_episode.tolist(), 'per_target_mean': per_episode.mean(0).tolist(),
                                   'roles': analysis}, indent=2))
        print(f'written to {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
