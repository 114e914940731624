"""`mate train mappo|ippo|iql|qmix|maddpg --team camera|target ...`: argument parser and runner (torch imported only when run)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..cli import CommandError, non_negative_int, number, positive_int, resolving_arguments

__all__ = ['add_arguments', 'config_from_args', 'run']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('algo', choices=('mappo', 'ippo', 'iql', 'qmix', 'maddpg'),
                        help='centralised (MAPPO) or local (IPPO) critic, independent Q-learning (IQL), value '
                             'decomposition with a monotonic mixer (QMIX), or MADDPG as MA-TD3 (continuous actions, '
                             'one actor and two centralised critics per agent)')
    parser.add_argument('--team', choices=('camera', 'target'), default='camera', help='team to train (default camera)')
    parser.add_argument('--config', '--cfg', default=None,
                        help='preset name (e.g. MATE-4v8-9) or YAML/JSON path; default: the paper preset of the team '
                             '(cameras MATE-4v8-9, targets MATE-2v4-0)')
    parser.add_argument('--steps', type=number(float, minimum=1), default=2e6, help='decision steps in total (default 2e6)')
    parser.add_argument('--minutes', type=float, default=0.0,
                        help='also stop after this many minutes of training wall time (resumed sessions included); '
                             'default 0: no time limit')
    parser.add_argument('--seed', type=non_negative_int, default=0)
    parser.add_argument('--num-envs', type=positive_int, default=None, help='batched games (default 64; IQL, QMIX and MADDPG 16)')
    parser.add_argument('--rollout-length', type=positive_int, default=25, help='decisions per env per iteration (default 25)')
    parser.add_argument('--epochs', type=positive_int, default=4)
    parser.add_argument('--minibatches', type=positive_int, default=4)
    parser.add_argument('--hrl', action='store_true',
                        help='cameras only: the policy selects targets (one bit per target), a rule executor aims (paper §HRL)')
    parser.add_argument('--actor', choices=('mlp', 'per-target'), default=None,
                        help="policy network: 'mlp' (paper) or, for cameras, 'per-target' (one shared scorer per target "
                             "slot); default per-target for cameras, mlp for targets")
    parser.add_argument('--paper', action='store_true',
                        help="the paper's MLP actor, its adaptive KL penalty (0.2, target 0.01) and its schedules "
                             "stretched over 10M steps (lr 5e-4 -> 1e-4 @4M -> 5e-5 @8M; entropy 0.05 -> 0.01 @2M -> "
                             "0.001 @4M -> 0 @10M); explicit options still win")
    parser.add_argument('--lstm', type=int, default=0, metavar='SIZE',
                        help='recurrent actor: MLP -> LSTM(SIZE) -> head, as in the paper (256); default 0, feed-forward')
    parser.add_argument('--comm', choices=('none', 'tarmac', 'i2c'), default='none',
                        help="'tarmac': the agents exchange learned messages (key 32 + value 32), read one decision "
                             "later through attention (the spec's TarMAC on the MLP body, LSTM of --lstm or 256 cells, "
                             "differentiable messages; the critic reads them too); 'i2c' (mappo, flat actions): one "
                             "network per agent, each asks the teammates its prior network selects for their current "
                             "observations and attends to them (prior trained on causal-influence labels of joint "
                             "action-value networks); deployed agents exchange messages through the env's channel; "
                             "default 'none'")
    parser.add_argument('--message-dropout', type=float, default=0.0, metavar='P',
                        help='with --comm: train under a lossy channel, each sender -> receiver delivery lost with '
                             'probability P in [0, 1] (as RandomMessageDropout; an I2C reply needs its request and '
                             'itself to get through); default 0')
    parser.add_argument('--communication-range', type=float, default=None, metavar='R',
                        help='with --comm: deliver a message only between agents at most R world units apart (as '
                             'RestrictedCommunicationRange); default: any distance')
    parser.add_argument('--message-delay', type=int, default=0, metavar='K',
                        help="with --comm tarmac: teammates' messages arrive K decisions late (on top of TarMAC's one; "
                             'as ExtraCommunicationDelays of K x frame-skip steps); default 0')
    parser.add_argument('--influence-samples', type=int, default=PPO_ONLY['influence_samples'], metavar='N',
                        help="with --comm i2c: decisions per iteration whose causal-influence labels are computed "
                             "(each costs N_agents x (N_agents - 1) x 25 x 25 joint action-value evaluations: the "
                             "largest share of an I2C iteration); default %(default)s")
    parser.add_argument('--full-observability', action='store_true',
                        help='the trained team sees every entity (the EnhancedObservation wrapper; the paper\'s Fig. 6 '
                             'ablation); evaluate such a policy with `mate evaluate --enhanced-observation TEAM`')
    parser.add_argument('--memory', type=int, default=0, metavar='STEPS',
                        help="cameras only: the team's shared memory of target sightings (every camera tells its "
                             "teammates what it sees; a sighting is kept STEPS env steps, the greedy cameras' 25), "
                             "appended to each camera's observation; default 0: none")
    parser.add_argument('--velocity', action='store_true',
                        help="cameras only: append each seen target's displacement over one held decision at its "
                             "current velocity (so that a policy holding its decision can aim ahead)")
    parser.add_argument('--credit', choices=('team', 'difference'), default='team',
                        help="cameras only: 'team' (default): every camera is rewarded with the team's coverage rate; "
                             "'difference': each camera with its own marginal contribution to it (the share of the "
                             "targets only it tracks), with one critic value per camera")
    parser.add_argument('--frame-skip', type=positive_int, default=None, help='default: 5 cameras, 10 targets')
    parser.add_argument('--horizon', type=positive_int, default=None, help='raw steps per training episode (default 500 decisions)')
    parser.add_argument('--gae-lambda', type=number(float, minimum=0), default=0.95)
    parser.add_argument('--kl-coeff', type=float, default=None,
                        help='initial coefficient of the adaptive KL penalty (RLlib and the paper: 0.2); '
                             'default 0: off (0.2 with --paper)')
    parser.add_argument('--kl-target', type=float, default=0.01,
                        help='KL per iteration the penalty adapts towards (x1.5 above twice, x0.5 below half; default 0.01)')
    parser.add_argument('--entropy-schedule', default=None, metavar='JSON',
                        help='[[step, coef], ...] piecewise linear (default 0.01 -> 0.001 @1M -> 0 @3M)')
    parser.add_argument('--lr-schedule', default=None, metavar='JSON',
                        help='[[step, lr], ...] step function (default 5e-4, 2e-4 @1.5M, 1e-4 @3M)')
    parser.add_argument('--snapshot-every', type=non_negative_int, default=0, metavar='N',
                        help='keep the policy every N iterations as RUN_DIR/snapshots/policy-STEPS.pt (default off)')
    parser.add_argument('--init-from', default=None, metavar='PATH',
                        help='warm start from the networks of a checkpoint or exported policy of the same setting '
                             '(steps and schedules start from 0)')
    parser.add_argument('--threads', type=non_negative_int, default=0,
                        help='torch threads of the update phase (default 0: every core; collection always uses 1)')
    value = parser.add_argument_group('off-policy (IQL, QMIX, MADDPG) options')
    value.add_argument('--buffer-size', type=positive_int, default=None,
                       help='replay size: IQL agent transitions (default 500,000), QMIX decision steps (default '
                            '1,000,000, as 2,000 episodes of 500), MADDPG decision steps (default 500,000)')
    value.add_argument('--batch-size', type=positive_int, default=1024,
                       help='samples per update: IQL agent transitions, QMIX and MADDPG decision steps (default 1024)')
    value.add_argument('--update-every', type=positive_int, default=128,
                       help='decision steps between updates (default 128, the spec\'s sampling round)')
    value.add_argument('--learning-starts', type=non_negative_int, default=5_000,
                       help='decision steps stored before the first update (default 5,000)')
    value.add_argument('--epsilon-schedule', default=None, metavar='JSON',
                       help='IQL, QMIX: [[step, epsilon], ...] piecewise linear (default 1.0 -> 0.02 @50k)')
    value.add_argument('--selection', choices=('joint', 'per-target'), default='joint',
                       help="IQL, QMIX with --hrl: 'joint' (default, the spec's Discrete(256)): one choice among the "
                            "2^Nt target subsets; 'per-target': a keep/ignore head per target slot")
    value.add_argument('--sequence-length', type=positive_int, default=25,
                       help='QMIX: decision steps per replay chunk of the recurrent agents (default 25)')
    parser.add_argument('--run-dir', default=None, help='output directory (default runs/ALGO-TEAM-seedN)')
    parser.add_argument('--fresh', action='store_true', help='ignore an existing checkpoint in the run directory')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar (CSV and TensorBoard only)')


def _env(config: str | None) -> dict:
    """The env keyword arguments of `--config`: a registered preset ID, or the config itself (read once here
    so that an unknown name or a bad file fails now, with the `ConfigError` listing the presets)."""
    if config is None:
        return {}
    from ..config import read_config
    from ..registration import registered_ids

    name = config.removesuffix('-v0')
    if f'{name}-v0' in registered_ids():
        return dict(env_id=f'{name}-v0')
    read_config(config)
    return dict(env_id='MultiAgentTracking-v0', config=config)


PPO_ONLY = dict(rollout_length=25, epochs=4, minibatches=4, actor=None, paper=False, lstm=0, full_observability=False,
                memory=0, velocity=False, gae_lambda=0.95, kl_coeff=None, kl_target=0.01, entropy_schedule=None,
                snapshot_every=0, init_from=None, comm='none', message_dropout=0.0,
                communication_range=None, message_delay=0, influence_samples=32)
"""The options of `mate train` that only the PPO trainers take, with their defaults."""
DQN_ONLY = dict(buffer_size=None, batch_size=1024, update_every=128, learning_starts=5_000, epsilon_schedule=None,
                sequence_length=25, selection='joint')
"""The options only the value-based trainers (IQL, QMIX) take, with their defaults."""
QMIX_ONLY = dict(sequence_length=25)
"""The value-based options only QMIX takes."""
NOT_MADDPG = dict(epsilon_schedule=None, sequence_length=25, lr_schedule=None, hrl=False, selection='joint')
"""Options MADDPG does not take (it has no epsilon, sequences, schedules or target selection)."""
VALUE_BASED = ('iql', 'qmix')


def _schedule(args: argparse.Namespace, key: str):
    text = getattr(args, key)
    try:
        return tuple(tuple(p) for p in json.loads(text))
    except (ValueError, TypeError) as exc:
        raise CommandError(f'--{key.replace("_", "-")} must be JSON [[step, value], ...]: {exc}')


def _refuse(args: argparse.Namespace, options: dict, algo: str) -> None:
    """CommandError naming the first of `options` given a non-default value (options of another trainer)."""
    for key, default in options.items():
        if getattr(args, key) != default:
            raise CommandError(f'--{key.replace("_", "-")} is not an option of {algo}')


def config_from_args(args: argparse.Namespace):
    """The `PPOConfig` (or `DQNConfig`) of parsed `mate train` arguments (CommandError, a SystemExit, with a
    message for bad ones)."""
    if not args.minutes >= 0:
        raise CommandError(f'--minutes must be >= 0 (0 = no time limit), got {args.minutes}')
    if args.hrl and args.team != 'camera':
        raise CommandError('--hrl exists for cameras only')
    if args.credit != 'team' and args.team != 'camera':
        raise CommandError(f'--credit {args.credit} (each camera\'s own share of the coverage) exists for '
                           'cameras only')
    if args.algo == 'maddpg':
        from .maddpg import MADDPGConfig

        _refuse(args, PPO_ONLY, 'MADDPG')
        _refuse(args, NOT_MADDPG, 'MADDPG')
        return MADDPGConfig(team=args.team, total_steps=int(args.steps), seed=args.seed, time_limit=60.0 * args.minutes,
                            num_envs=args.num_envs or 16, frame_skip=args.frame_skip, horizon=args.horizon,
                            credit=args.credit, buffer_size=args.buffer_size or 500_000, batch_size=args.batch_size,
                            update_every=args.update_every, learning_starts=args.learning_starts,
                            torch_threads=args.threads or 1, **_env(args.config))
    if args.algo in VALUE_BASED:
        from .dqn import DQNConfig

        _refuse(args, PPO_ONLY, args.algo.upper())
        if args.algo == 'iql':
            _refuse(args, QMIX_ONLY, 'IQL')
        extra = {key: _schedule(args, key) for key in ('lr_schedule', 'epsilon_schedule') if getattr(args, key)}
        return DQNConfig(algo=args.algo, team=args.team, total_steps=int(args.steps), seed=args.seed,
                         time_limit=60.0 * args.minutes, num_envs=args.num_envs or 16, frame_skip=args.frame_skip,
                         horizon=args.horizon, hrl=args.hrl, credit=args.credit, buffer_size=args.buffer_size,
                         batch_size=args.batch_size, update_every=args.update_every,
                         sequence_length=args.sequence_length, learning_starts=args.learning_starts,
                         selection=args.selection,
                         torch_threads=args.threads or 1, **_env(args.config), **extra)
    from .ppo import PAPER_HYPERPARAMETERS, PPOConfig

    _refuse(args, DQN_ONLY, args.algo.upper())
    extra = dict(PAPER_HYPERPARAMETERS) if args.paper else {}
    if args.actor:
        extra['actor'] = args.actor
    for key in ('entropy_schedule', 'lr_schedule'):
        if getattr(args, key):
            extra[key] = _schedule(args, key)
    if args.kl_coeff is not None:
        if not args.kl_coeff >= 0:
            raise CommandError(f'--kl-coeff must be >= 0 (0 = no KL penalty), got {args.kl_coeff}')
        extra['kl_coeff'] = args.kl_coeff
    if not args.kl_target > 0:
        raise CommandError(f'--kl-target must be > 0, got {args.kl_target}')
    if args.lstm < 0:
        raise CommandError(f'--lstm must be >= 0 (0 = feed-forward), got {args.lstm}')
    if args.memory < 0:
        raise CommandError(f'--memory must be >= 0 steps (0 = no memory), got {args.memory}')
    if args.memory and args.team != 'camera':
        raise CommandError('--memory (shared sightings of targets) exists for cameras only')
    if args.velocity and args.team != 'camera':
        raise CommandError('--velocity (motion of the seen targets) exists for cameras only')
    if args.actor == 'per-target' and args.team != 'camera':
        raise CommandError("--actor per-target reads a camera's target slots; it needs --team camera")
    if args.comm == 'i2c':
        for flag, given, reason in (('--hrl', args.hrl, 'needs the flat discrete actions'),
                                    ('--memory', args.memory, 'exchanges raw observations'),
                                    ('--velocity', args.velocity, 'exchanges raw observations')):
            if given:
                raise CommandError(f'--comm i2c {reason}; {flag} does not combine with it')
        if args.algo != 'mappo':
            raise CommandError(f'--comm i2c is a MAPPO add-on (its Q-networks read the global state); '
                               f'use mate train mappo, not {args.algo}')
    if not 0.0 <= args.message_dropout <= 1.0:
        raise CommandError(f'--message-dropout must be a probability in [0, 1], got {args.message_dropout}')
    if args.communication_range is not None and not args.communication_range > 0:
        raise CommandError(f'--communication-range must be a distance > 0 (world units), got {args.communication_range}')
    if args.message_delay < 0:
        raise CommandError(f'--message-delay must be a whole number of decisions >= 0, got {args.message_delay}')
    if args.comm == 'none':
        for flag, given in (('--message-dropout', args.message_dropout > 0),
                            ('--communication-range', args.communication_range is not None),
                            ('--message-delay', args.message_delay > 0)):
            if given:
                raise CommandError(f'{flag} perturbs learned messages; it needs --comm tarmac or --comm i2c')
    if args.influence_samples != PPO_ONLY['influence_samples'] and args.comm != 'i2c':
        raise CommandError('--influence-samples sets how I2C labels its prior; it needs --comm i2c')
    if args.influence_samples < 1:
        raise CommandError(f'--influence-samples must be a number of decisions >= 1, got {args.influence_samples}')
    if args.comm == 'i2c' and args.message_delay:
        raise CommandError('--message-delay is a TarMAC option: an I2C reply later than its decision is never read '
                           '(train that with --message-dropout 1)')
    if args.comm != 'none' and args.actor == 'per-target':
        raise CommandError(f'--comm {args.comm} builds its actor on the MLP body; --actor per-target does not '
                           'combine with it')
    return PPOConfig(algo=args.algo, team=args.team, total_steps=int(args.steps), seed=args.seed,
                     time_limit=60.0 * args.minutes,
                     num_envs=args.num_envs or 64, rollout_length=args.rollout_length, epochs=args.epochs,
                     minibatches=args.minibatches, frame_skip=args.frame_skip, horizon=args.horizon,
                     gae_lambda=args.gae_lambda, kl_target=args.kl_target, torch_threads=args.threads,
                     snapshot_every=args.snapshot_every,
                     lstm=args.lstm, comm=args.comm, message_dropout=args.message_dropout,
                     communication_range=args.communication_range,
                     message_delay=args.message_delay, influence_samples=args.influence_samples, hrl=args.hrl,
                     full_observability=args.full_observability,
                     memory=args.memory, velocity=args.velocity, credit=args.credit, init_from=args.init_from,
                     **_env(args.config), **extra)


def run(args: argparse.Namespace, console) -> int:
    """Train as `args` say; 0 when done (or already done), 130 when interrupted (resumable)."""
    try:
        from .checkpoint import CheckpointError, load_checkpoint
        from .dqn import train_dqn
        from .maddpg import train_maddpg
        from .ppo import train
    except ImportError as exc:
        raise CommandError(f"needs PyTorch ({exc}); install the training extra: pip install 'mate[train]'") from None

    with resolving_arguments():
        config = config_from_args(args)
        resolved = config.resolved()
    name = ((f'hrl-{args.algo}' if args.hrl else args.algo) + (f'-{args.comm}' if args.comm != 'none' else '')
            + ('-full-obs' if args.full_observability else '')
            + (f'-dropout{args.message_dropout:g}' if getattr(args, 'message_dropout', 0.0) > 0 else '')
            + (f'-range{args.communication_range:g}' if getattr(args, 'communication_range', None) is not None else '')
            + (f'-delay{args.message_delay}' if getattr(args, 'message_delay', 0) > 0 else ''))
    run_dir = Path(args.run_dir or f'runs/{name}-{args.team}-seed{args.seed}')
    checkpoint_path = run_dir / 'checkpoint.pt'
    resuming = checkpoint_path.exists() and not args.fresh
    if resuming:   # (a resumed run ignores --init-from)
        try:
            done = _already_done(load_checkpoint(checkpoint_path), config)
        except CheckpointError as exc:
            raise CommandError(f'{exc} (use --fresh or another --run-dir to start over)') from None
        if done:
            reason, flag = done
            console.print(f'run already done: {reason} (use --fresh to start over or raise {flag})', soft_wrap=True)
            return 0
    elif getattr(config, 'init_from', None):   # a bad file fails now, before the envs are built
        try:
            load_checkpoint(config.init_from)
        except CheckpointError as exc:
            raise CommandError(f'--init-from: {exc}') from None
    comm = getattr(resolved, 'comm', 'none')
    network = (f'TarMAC actor, LSTM {resolved.lstm}' if comm == 'tarmac' else
               f'I2C actors, LSTM {resolved.lstm}, one per agent' if comm == 'i2c' else
               f'{resolved.actor} actor' if hasattr(resolved, 'actor') else
               {'qmix': 'GRU agent network, mixer', 'iql': 'dueling Q-network',
                'maddpg': 'an actor and twin critics per agent, continuous actions'}[args.algo])
    if (getattr(resolved, 'message_dropout', 0.0) > 0 or getattr(resolved, 'communication_range', None) is not None
            or getattr(resolved, 'message_delay', 0) > 0):
        network += (f', channel: message dropout {resolved.message_dropout}, communication range '
                    f'{resolved.communication_range if resolved.communication_range is not None else "any"}, '
                    f'extra delay {resolved.message_delay}')
    console.print(f'training {name.upper()} {args.team}s on {resolved.env_id} ({network}, frame skip '
                  f'{resolved.frame_skip}, {config.num_envs} envs, {config.total_steps:,} decision steps) -> {run_dir}')
    if resuming:
        console.print(f'resuming from {checkpoint_path}')
    try:
        trainer = {'iql': train_dqn, 'qmix': train_dqn, 'maddpg': train_maddpg}.get(args.algo, train)
        row = trainer(config, run_dir, resume=not args.fresh, progress=not args.no_progress)
    except CheckpointError as exc:   # the run directory's checkpoint belongs to another experiment
        raise CommandError(f'{exc} (use --fresh or another --run-dir to start over)') from None
    except KeyboardInterrupt:
        console.print(f'interrupted; run the same command again to resume from {checkpoint_path}')
        return 130
    if config.time_limit and row.get('env_steps', config.total_steps) < config.total_steps:
        console.print(f'stopped at the time limit of {args.minutes:g} minutes')
    console.print(f"done: {row.get('env_steps', 0):,} decision steps, coverage {row.get('rollout_coverage', float('nan')):.3f}, "
                  f"episode return {row.get('episode_return', float('nan')):.1f}; final policy {run_dir / 'final.pt'}")
    return 0


def _already_done(saved: dict, config) -> tuple[str, str] | None:
    """Why the run of checkpoint `saved` needs no more training under `config`, and the flag to raise
    to train on; None if it does need more."""
    steps, seconds = int(saved.get('env_steps', 0)), float(saved.get('wall_seconds', 0.0))
    if steps >= config.total_steps:
        return f'{steps:,} decision steps >= --steps {config.total_steps:,}', '--steps'
    if config.time_limit and seconds >= config.time_limit:
        return f'{seconds / 60:.3g} minutes of training >= --minutes {config.time_limit / 60:g}', '--minutes'
    return None
