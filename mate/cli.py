"""The `mate` command line: `mate evaluate`, `mate train`, `mate psro`, `mate bench`, `mate generate-config`, ...

Each sub-command lives in a small function that parses nothing itself: `main` builds the
argument parser, and the sub-command receives the parsed namespace.

Errors: a mistake in the arguments (a number out of range, an unknown preset or agent, a bad
checkpoint, a missing file) prints one line, `mate COMMAND: error: MESSAGE`, and exits with
status 2; `mate --debug ...` (or the environment variable MATE_DEBUG=1) prints the traceback too.
Any other exception is a bug and shows its traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback

from rich.console import Console
from rich.table import Table

from .arguments import ArgumentParser, CommandError, non_negative_int, number, positive_int, resolving_arguments

console = Console()
TEAM_CHOICES = ('both', 'camera', 'target', 'none')
USER_OS_ERRORS = (FileNotFoundError, FileExistsError, IsADirectoryError, NotADirectoryError, PermissionError)
"""Errors about the user's paths, reported in one line like argument mistakes."""
DEBUG_HELP = 'on an error, also print the traceback (or set the environment variable MATE_DEBUG=1)'


def _debugging(args: argparse.Namespace) -> bool:
    return getattr(args, 'debug', False) or os.environ.get('MATE_DEBUG', '').strip() not in ('', '0')


def _is_user_error(exc: BaseException) -> bool:
    """Whether `exc` reports a mistake in the command's input rather than a bug."""
    from .config import ConfigError

    if isinstance(exc, (CommandError, ConfigError, *USER_OS_ERRORS)):
        return True
    checkpoint = sys.modules.get('mate.learn.checkpoint')   # imported if it raised (importing it needs torch)
    return checkpoint is not None and isinstance(exc, checkpoint.CheckpointError)


def _bench(args: argparse.Namespace) -> int:
    from . import bench

    batch_sizes = (1, 64, 1024) if args.quick else tuple(args.batch_sizes)
    seconds = 0.5 if args.quick else args.seconds
    with console.status('compiling and measuring...') as status:
        results = bench.run(args.presets, batch_sizes, seconds, float32=not args.quick,
                            progress=lambda text: status.update(f'measuring {text}'), repeat=args.repeat)
    columns = (['preset', 'what', 'B', 'obs dtype', 'env-steps/s'] + (['median'] if args.repeat > 1 else [])
               + ['x single env', 'x original'])
    rounds = f', best of {args.repeat} rounds' if args.repeat > 1 else ''
    table = Table(title=f'mate throughput (random actions, observations built{rounds})')
    for column in columns:
        table.add_column(column, justify='left' if column in ('preset', 'what', 'obs dtype') else 'right')
    for r in results:
        speedup = f"{r['speedup_vs_original']:,.0f}x" if r['speedup_vs_original'] else '-'
        median = [f"{r['median_env_steps_per_second']:,.0f}"] if args.repeat > 1 else []
        table.add_row(r['preset'], r['kind'], str(r['batch_size']), r['dtype'],
                      f"{r['env_steps_per_second']:,.0f}", *median, f"{r['speedup_vs_single_env']:,.1f}x", speedup)
    console.print(table)
    facts = bench.machine_facts()
    console.print(f"machine: {facts['cpus']} cores, {facts['processor']}, numba {facts['numba']}. The ratios hold "
                  "across machines; the absolute numbers differ between CPU families by 2x and more", soft_wrap=True)
    if args.json:
        console.print(f'results written to {bench.write_json(results, args.json)}')
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from . import evaluate as ev
    from .messages import Team
    from .progress import ProgressLine
    from .registration import make

    require_torch_agents((args.camera_agent, args.target_agent))
    batched, reason = _evaluation_path(args)
    if batched:
        return _evaluate_batched(args)
    with resolving_arguments():
        camera_cls = ev.resolve_agent(args.camera_agent, Team.CAMERA)
        target_cls = ev.resolve_agent(args.target_agent, Team.TARGET)
        camera_kwargs = _json_kwargs(args.camera_kwargs, '--camera-kwargs')
        target_kwargs = _json_kwargs(args.target_kwargs, '--target-kwargs')
        env = make('MultiAgentTracking-v0', config=args.config, wrappers=_evaluation_wrappers(args))
        camera_factory = lambda seed: camera_cls(**{**camera_kwargs, 'seed': seed})  # noqa: E731
        target_factory = lambda seed: target_cls(**{**target_kwargs, 'seed': seed})  # noqa: E731
    for flag, factory in (('--camera-kwargs', camera_factory), ('--target-kwargs', target_factory)):
        try:
            factory(seed=args.seed)      # an agent now, so that bad keyword arguments fail before any episode
        except (TypeError, ValueError) as exc:
            raise CommandError(f'{flag}: {exc}') from exc
    with resolving_arguments():          # agents that refuse this game (a policy trained for another preset) say so now
        ev.check_agents_fit(env, camera_factory, target_factory, args.seed)
    console.print(f'environment: {env} (single env, one episode after the other: {reason})', soft_wrap=True)
    console.print(f'cameras: {args.camera_agent} {camera_kwargs or ""}  '
                  f'targets: {args.target_agent} {target_kwargs or ""}')
    _say_true_state(args)

    recorder = _recorder(args)
    results = []
    from .core.jit import compile_seconds

    compiled = compile_seconds()
    with ProgressLine('evaluating', total=args.episodes, console=console, transient=True) as progress:
        for episode in range(args.episodes):
            result = ev.play_episode(env, camera_factory, target_factory, args.seed + episode,
                                     args.max_episode_steps, recorder if episode == 0 else None)
            results.append(result)
            progress.update(advance=1, status=f'coverage {result.coverage_rate:.3f}, '
                                              f'{result.steps_per_second:,.0f} steps/s')
    compiled = compile_seconds() - compiled
    summary = _report(env, args, results)
    if compiled >= 0.05:
        console.print(f"(the first episode's speed includes {_compiling(compiled)})")
    _finish_recording(recorder, args)
    _write_results(args, results, summary)
    return 0


def _compiling(seconds: float) -> str:
    """What a first run's timing includes: '18.3 s of compiling the simulation kernels (...)'."""
    return f'{seconds:.1f} s of compiling the simulation kernels: a first run; later runs load them from the cache'


def _evaluation_path(args: argparse.Namespace) -> tuple[bool, str]:
    """(whether `mate evaluate` plays batched, why the single env if not): batched whenever both teams have a
    batched form and no wrapper is asked for, unless --single-env; --batched insists (one-line error if it
    cannot be)."""
    from . import evaluate as ev

    wrappers = [f'--{flag.replace("_", "-")}' for flag in ('enhanced_observation', 'shared_field_of_view',
                                                            'no_communication') if getattr(args, flag) != 'none']
    if args.render_communication:
        wrappers.append('--render-communication')
    unbatched = [agent for agent in (args.camera_agent, args.target_agent) if not ev.has_batched_team(agent)]
    if args.batched and args.single_env:
        raise CommandError('--batched and --single-env exclude each other')
    if args.batched and (wrappers or unbatched):
        problem = (f'plays the game without wrappers; drop {", ".join(wrappers)}' if wrappers else
                   f'has no batched form of {", ".join(unbatched)} (batched agents: random, greedy, upper-bound, '
                   'checkpoint:PATH, pretrained:NAME)')
        raise CommandError(f'--batched {problem}, or --batched')
    if args.single_env:
        return False, '--single-env'
    if wrappers:
        return False, f'the wrappers {", ".join(wrappers)} need it'
    if unbatched:
        return False, f'{", ".join(unbatched)} has no batched form'
    return True, ''


def _say_true_state(args: argparse.Namespace) -> None:
    from . import evaluate as ev

    if args.camera_agent in ev.SEES_TRUE_STATE:
        console.print(f'{args.camera_agent} cameras see the true state (every target\'s position every step): a '
                      'reference, not a camera team of the game', soft_wrap=True)


def _policy_device(args: argparse.Namespace):
    """The torch device of `mate evaluate --device` for batched policies ('cpu' when no policy plays: no torch)."""
    from .learn.device import parse_device, resolve_device   # imports no torch

    parse_device(args.device)
    agents = (args.camera_agent, args.target_agent)
    if not any(agent.partition(':')[0] in ('checkpoint', 'pretrained') for agent in agents):
        return 'cpu'
    return resolve_device(args.device)


DEFAULT_GIF = 'mate-evaluate.gif'
"""Where `mate evaluate` saves the first episode when no --save-gif is given (and the render extra is installed)."""


def require_torch_agents(agents) -> None:
    """A one-line error when trained policies (`checkpoint:PATH`, `pretrained:NAME`) are asked for without torch."""
    from .extras import require

    for agent in agents:
        if agent.partition(':')[0] in ('checkpoint', 'pretrained'):
            require('train', f'the agent {agent}')


def _recorder(args: argparse.Namespace):
    """The frame recorder of the first episode, or None when nothing is recorded. Without the render extra the
    default GIF is left out with a note, while an explicit --save-gif or --save-video is a one-line error."""
    from . import evaluate as ev
    from .extras import missing, require

    if args.save_gif is None:
        args.save_gif = DEFAULT_GIF
        if not args.no_render and missing('render'):
            console.print("no GIF of the first episode: rendering needs the render extra (pip install "
                          "'mate[render]'); --no-render says nothing", soft_wrap=True, highlight=False)
            args.save_gif = ''
    if args.no_render or not (args.save_gif or args.save_video):
        return None
    require('render', '--save-gif' if args.save_gif else '--save-video')
    return ev.FrameRecorder(args.frame_size, args.frame_every, hud=not args.no_hud,
                            max_episode_steps=args.max_episode_steps)


def _finish_recording(recorder, args: argparse.Namespace) -> None:
    if recorder is not None:
        recorder.close()
        _save_frames(recorder.frames, args)


def _report(env, args: argparse.Namespace, results: list) -> list[dict]:
    """Print the summary table of `results`; returns the summary rows."""
    from . import evaluate as ev
    summary = ev.summarise(results)
    _print_summary(env, args, summary)
    return summary


def _write_results(args: argparse.Namespace, results: list, summary: list[dict]) -> None:
    """`--json PATH`: the settings, the summary and every episode."""
    if args.json:
        from . import evaluate as ev
        settings = {k: v for k, v in vars(args).items() if k != 'run'}
        console.print(f'episode results written to {ev.write_json(args.json, settings, results, summary)}')


def _evaluate_batched(args: argparse.Namespace) -> int:
    from . import evaluate as ev
    from .progress import ProgressLine
    from .registration import make

    from .messages import Team

    with resolving_arguments():
        device = _policy_device(args)
        camera_kwargs = _json_kwargs(args.camera_kwargs, '--camera-kwargs')
        target_kwargs = _json_kwargs(args.target_kwargs, '--target-kwargs')
        env = make('MultiAgentTracking-v0', config=args.config)
        for agent, team in ((args.camera_agent, Team.CAMERA), (args.target_agent, Team.TARGET)):
            ev.resolve_agent(agent, team)        # unknown names first, with the usual message
    teams = []
    for agent, team, kwargs, flag in ((args.camera_agent, Team.CAMERA, camera_kwargs, '--camera-kwargs'),
                                      (args.target_agent, Team.TARGET, target_kwargs, '--target-kwargs')):
        try:
            teams.append(ev.batched_team(env, agent, team, args.episodes, args.seed, kwargs, device=device))
        except (TypeError, ValueError) as exc:
            raise CommandError(f'{flag}: {exc}' if kwargs else str(exc)) from exc
    cameras, targets = teams
    console.print(f'environment: {env} (batched: {args.episodes} games at once in one vector env)', soft_wrap=True)
    console.print(f'cameras: {args.camera_agent} {camera_kwargs or ""}  '
                  f'targets: {args.target_agent} {target_kwargs or ""}')
    _say_true_state(args)
    recorder = _recorder(args)
    from .core.jit import compile_seconds

    compiled = compile_seconds()
    with ProgressLine('evaluating', total=args.episodes, console=console, transient=True) as progress:
        results = ev.play_batched(args.config, cameras, targets, args.episodes, args.seed, args.max_episode_steps,
                                  progress=lambda done, total: progress.update(completed=done), recorder=recorder)
    compiled = compile_seconds() - compiled
    summary = _report(env, args, results)
    console.print(f'{sum(r.episode_length for r in results):,} env steps at {results[0].steps_per_second:,.0f} '
                  f'env-steps/s (whole batch' + (f', including {_compiling(compiled)})' if compiled >= 0.05 else ')'))
    _finish_recording(recorder, args)
    _write_results(args, results, summary)
    return 0


def _json_kwargs(text: str, flag: str) -> dict:
    import json
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CommandError(f'{flag} is not valid JSON ({exc}): {text!r}') from None
    if not isinstance(value, dict):
        raise CommandError(f'{flag} must be a JSON object, got {text!r}')
    return value


def _evaluation_wrappers(args: argparse.Namespace) -> list:
    """The single env's wrappers: those asked for, and `EnhancedObservation` on the cameras for camera agents that
    see the true state (`mate.evaluate.SEES_TRUE_STATE`: upper-bound)."""
    from . import evaluate as ev
    from . import wrappers
    stack = []
    for flag, wrapper in (('enhanced_observation', wrappers.EnhancedObservation),
                          ('shared_field_of_view', wrappers.SharedFieldOfView),
                          ('no_communication', wrappers.NoCommunication)):
        team = getattr(args, flag)
        if flag == 'enhanced_observation' and args.camera_agent in ev.SEES_TRUE_STATE:
            team = {'none': 'camera', 'target': 'both'}.get(team, team)
        if team != 'none':
            stack.append(lambda env, w=wrapper, t=team: w(env, team=t))
    if args.render_communication:
        stack.append(lambda env: wrappers.RenderCommunication(env, duration=args.render_communication,
                                                              kinds=args.message_kinds))
    return stack


def _print_summary(env, args: argparse.Namespace, summary: list[dict]) -> None:
    table = Table(title=f'{env.name}: {args.camera_agent} cameras vs {args.target_agent} targets, '
                        f'{args.episodes} episode{"s" if args.episodes > 1 else ""} (seeds {args.seed}..'
                        f'{args.seed + args.episodes - 1}, at most {args.max_episode_steps} steps)')
    for column in ('team', 'metric', 'mean', 'std'):
        table.add_column(column, justify='right' if column in ('mean', 'std') else 'left')
    for row in summary:
        digits = 1 if abs(row['mean']) >= 100 else 4
        table.add_row(row['team'], row['metric'], f"{row['mean']:,.{digits}f}", f"{row['std']:,.{digits}f}")
    console.print(table)


def _save_frames(frames: list, args: argparse.Namespace) -> None:
    from .video import save_gif, save_video
    fps = max(1, round(30 / args.frame_every))
    if args.save_gif:
        console.print(f'first episode ({len(frames)} frames) saved to {save_gif(frames, args.save_gif, fps=fps)}')
    if args.save_video:
        console.print(f'first episode video saved to {save_video(frames, args.save_video, fps=fps)}')


def _generate_config(args: argparse.Namespace) -> int:
    from .generator import GENERATION_SECONDS, ITERATIONS, RESTARTS, check_config_path, generate_config, plot_config, \
        write_config
    from .progress import ProgressLine

    with resolving_arguments():
        check_config_path(args.path)
        if args.num_cameras:
            console.print(f'placing {args.num_cameras} cameras: {RESTARTS} runs of up to {ITERATIONS:,} Adam steps '
                          f'over a 101 x 101 mesh ({GENERATION_SECONDS} s for 6 cameras on 2 cores)', soft_wrap=True)
        with ProgressLine('placing cameras', total=RESTARTS * ITERATIONS, console=console, transient=True) as line:
            def placed(restart: int, iteration: int, covering: float) -> None:
                line.update(completed=restart * ITERATIONS + iteration,
                            status=f'run {restart + 1}/{RESTARTS}, covering distance {covering:.1f}')

            config = generate_config(args.num_cameras, args.num_targets, args.num_obstacles,
                                     args.num_cargoes_per_target, args.obstacle_transmittance, args.seed,
                                     progress=placed)
    path = write_config(config, args.path)
    console.print(f"wrote {path}: {config['name']}")
    if 'camera' in config:
        console.print(f"camera max_sight_range {config['camera']['max_sight_range']:.1f}, "
                      f"radius {config['camera']['radius']:.1f}")
    if args.plot:
        try:
            console.print(f'plot written to {plot_config(config, args.plot)}')
        except ImportError as exc:   # matplotlib missing
            raise CommandError(str(exc)) from exc
    return 0


def _presets(args: argparse.Namespace) -> int:
    from .config import list_presets, read_config

    table = Table(title='shipped presets')
    for column in ('preset', 'cameras', 'targets', 'obstacles', 'reward'):
        table.add_column(column)
    for name in list_presets():
        config = read_config(name)
        counts = [len(config.get(section, {}).get('location', [])) +
                  len(config.get(section, {}).get('location_random_range', []))
                  for section in ('camera', 'target', 'obstacle')]
        table.add_row(name, *map(str, counts), config['reward_type'])
    console.print(table)
    return 0


def _rllib_train(args: argparse.Namespace) -> int:
    from .integrations import rllib_train

    return rllib_train.run(args, console)


def _train(args: argparse.Namespace) -> int:
    from .extras import require
    from .learn import command

    require('train', 'mate train')

    return command.run(args, console)


def _psro(args: argparse.Namespace) -> int:
    from .extras import require
    from .learn.population import command

    require('train', 'mate psro')

    return command.run(args, console)


def _benchmark(args: argparse.Namespace) -> int:
    from .benchmark import command
    from .extras import require

    require('train', 'mate benchmark')   # its jobs train, its reports need scipy's statistics and matplotlib

    return command.run(args, console)


def build_parser() -> argparse.ArgumentParser:
    debug = argparse.ArgumentParser(add_help=False)   # --debug before or after the command name
    debug.add_argument('--debug', action='store_true', default=argparse.SUPPRESS, help=DEBUG_HELP)
    parser = ArgumentParser(
        prog='mate', description='MATE: the Multi-Agent Tracking Environment', parents=[debug],
        epilog='A mistake in the arguments prints one line and exits with status 2; add --debug (mate --debug '
               'COMMAND ...) or set MATE_DEBUG=1 to see the traceback too.')
    from . import __version__
    parser.add_argument('--version', action='version', version=f'mate {__version__}')
    commands = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')

    def command(name: str, **kwargs) -> argparse.ArgumentParser:
        return commands.add_parser(name, parents=[debug], **kwargs)

    bench = command('bench', help='measure env-steps/s of the single env and the batched core')
    bench.add_argument('--presets', nargs='+', default=['MATE-4v8-9', 'MATE-8v8-9'])
    bench.add_argument('--batch-sizes', nargs='+', type=positive_int, default=[1, 64, 1024, 4096, 16384])
    bench.add_argument('--seconds', type=number(float, above=0), default=2.0, help='time per measurement (default 2)')
    bench.add_argument('--repeat', type=positive_int, default=1,
                       help="rounds of the whole plan; report each measurement's best round and the median "
                            '(default 1)')
    bench.add_argument('--quick', action='store_true', help='small batches, 0.5 s each, no float32 runs')
    bench.add_argument('--json', default=None, help='also write the results to this JSON file')
    bench.set_defaults(run=_bench)

    evaluate = command(
        'evaluate', help='play camera agents against target agents and summarise the episodes',
        description='Play episodes (episode i: a fresh env reset with seed + i, agents seeded alike) and print '
                    'mean and std of coverage, transport and returns per team. By default greedy cameras play '
                    'greedy targets on MATE-4v8-9 and the first episode is saved as a GIF.')
    evaluate.add_argument('--config', '--cfg', default='MATE-4v8-9',
                          help='preset name or YAML/JSON path (default MATE-4v8-9)')
    evaluate.add_argument('--camera-agent', default='greedy',
                          help='random|naive|greedy|heuristic|mixture|upper-bound, module:Class, checkpoint:PATH or '
                               'pretrained:NAME (upper-bound: a centralised reference that sees the true state)')
    evaluate.add_argument('--target-agent', default='greedy', help='as --camera-agent')
    evaluate.add_argument('--camera-kwargs', default='{}', help='JSON keyword arguments of the camera agent')
    evaluate.add_argument('--target-kwargs', default='{}', help='JSON keyword arguments of the target agent')
    evaluate.add_argument('--episodes', type=positive_int, default=20, help='episodes to play (default 20)')
    evaluate.add_argument('--seed', type=non_negative_int, default=0, help='episode i uses seed + i (agents too)')
    evaluate.add_argument('--max-episode-steps', type=positive_int, default=2000,
                          help='step cap per episode (default 2000)')
    for flag in ('enhanced-observation', 'shared-field-of-view', 'no-communication'):
        evaluate.add_argument(f'--{flag}', nargs='?', const='both', default='none', choices=TEAM_CHOICES,
                              metavar='TEAM',
                              help=f'add the {flag.replace("-", " ")} wrapper for TEAM (bare flag: both)')
    evaluate.add_argument('--render-communication', nargs='?', type=positive_int, const=20, default=None,
                          metavar='DURATION',
                          help='draw message arrows in the recorded frames, each for DURATION steps after it was sent '
                               '(bare flag: 20)')
    evaluate.add_argument('--message-kinds', action='store_true',
                          help='with --render-communication: draw requests orange dashed, replies purple solid and '
                               'broadcasts dashed in the team colour (default: blue camera / red target arrows)')
    evaluate.add_argument('--no-render', action='store_true', help='record nothing (no GIF, no video)')
    evaluate.add_argument('--save-gif', default=None, metavar='PATH',
                          help=f'GIF of the first episode (default {DEFAULT_GIF} when the render extra is installed; '
                               'empty string: none)')
    evaluate.add_argument('--save-video', default=None, metavar='PATH', help='MP4 of the first episode')
    evaluate.add_argument('--frame-size', type=number(int, minimum=16), default=600,
                          help='recorded frame size in pixels, at least 16 (default 600)')
    evaluate.add_argument('--no-hud', action='store_true',
                          help='no heads-up line (step, coverage, delivered cargo) in the recorded frames')
    evaluate.add_argument('--frame-every', type=positive_int, default=4, help='record every N-th step (default 4)')
    evaluate.add_argument('--json', default=None, metavar='PATH', help='write per-episode results and the summary')
    evaluate.add_argument('--batched', action='store_true',
                          help='insist on playing every episode at once in one vector env (the default whenever both '
                               'agents have a batched form: random, greedy, upper-bound, checkpoint:PATH, '
                               'pretrained:NAME, and no wrapper is asked for): an error if it cannot. The rule agents '
                               'play the same episodes either way; policies that sample draw from other random streams')
    evaluate.add_argument('--device', default='cpu',
                          help='where batched policies (checkpoint:, pretrained:) run their forward passes: cpu '
                               '(default), cuda, cuda:N or auto; the games are played on the CPU')
    evaluate.add_argument('--single-env', action='store_true',
                          help='play the episodes one after the other in the single env with per-agent objects (the '
                               'path of agents without a batched form, and of wrappers)')
    evaluate.set_defaults(run=_evaluate)

    generate = command('generate-config', help='write a config with camera placement covering the terrain')
    generate.add_argument('--path', default='config.yaml', help='output YAML file (default config.yaml)')
    generate.add_argument('--num-cameras', type=non_negative_int, default=4, help='default 4')
    generate.add_argument('--num-targets', type=positive_int, default=8, help='default 8')
    generate.add_argument('--num-obstacles', type=non_negative_int, default=0, help='default 0')
    generate.add_argument('--num-cargoes-per-target', type=number(int, minimum=4), default=8,
                          help='at least 4 (default 8)')
    generate.add_argument('--obstacle-transmittance', type=number(float), default=0.1, help='clipped to [0, 1]')
    generate.add_argument('--seed', type=non_negative_int, default=0)
    generate.add_argument('--plot', default=None, metavar='PNG', help='also save a picture of the placement')
    generate.set_defaults(run=_generate_config)

    presets = command('presets', help='list the shipped configuration presets')
    presets.set_defaults(run=_presets)

    from .integrations.rllib_train import add_arguments as add_rllib_train_arguments  # imports no Ray
    rllib_train = command('rllib-train',
                          help="train a team with RLlib's PPO as a mate train run (the witness; Ray RLlib)")
    add_rllib_train_arguments(rllib_train)
    rllib_train.set_defaults(run=_rllib_train)

    from .learn.command import add_arguments as add_train_arguments  # imports no torch
    train = command('train',
                    help='train MAPPO/IPPO/IQL/QMIX/MADDPG cameras or targets against greedy opponents (PyTorch)')
    add_train_arguments(train)
    train.set_defaults(run=_train)

    from .learn.population.command import add_arguments as add_psro_arguments  # imports no torch
    psro = command('psro',
                   help='population training: PSRO-Nash, fictitious self-play or self-play, with exploitability',
                   description='Grow a camera pool and a target pool by best responses to the other pool\'s '
                               'meta-strategy (paper §5.3): HRL-MAPPO cameras, MAPPO targets, payoff '
                               'entries played in batches, exploitability (paper Eq. 2) per iteration. Everything is '
                               'saved after each stage; the same command resumes a killed run. "mate psro plot '
                               'DIR..." draws the figures.')
    add_psro_arguments(psro)
    psro.set_defaults(run=_psro)

    from .benchmark.command import add_arguments as add_benchmark_arguments  # imports no torch
    benchmark = command('benchmark', help="the paper's experiments: list, run (resumable jobs), report (IQM, CIs, "
                                          'marl_eval.json)',
                        description="The paper's experiments as data: \"mate benchmark list\" names them, \"mate "
                                    'benchmark run NAME\" runs every missing (setting, seed) job with evaluations on '
                                    'held-out seeds, "mate benchmark report DIR..." writes figures, a markdown table '
                                    'and marl_eval.json with interquartile means and 95 % bootstrap intervals.')
    add_benchmark_arguments(benchmark)
    benchmark.set_defaults(run=_benchmark)
    return parser


def _chosen_parser(parser: argparse.ArgumentParser, args: argparse.Namespace) -> argparse.ArgumentParser:
    """The parser of the (sub)command `args` chose: `mate evaluate`'s, `mate benchmark run`'s, ..."""
    while True:
        commands = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
        chosen = getattr(args, commands[0].dest, None) if commands else None
        if chosen not in (commands[0].choices if commands else {}):
            return parser
        parser = commands[0].choices[chosen]


def main(argv: list[str] | None = None) -> int:
    """Run `mate ARGS`; returns the exit status (argparse's own errors exit with status 2; Ctrl-C: 130)."""
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:                         # said by the subcommand that was given them: `mate evaluate: error: ...`
        _chosen_parser(parser, args).error(f'unrecognized arguments: {" ".join(unknown)}')
    try:
        return args.run(args)
    except KeyboardInterrupt:
        if _debugging(args):
            traceback.print_exc()
        print(f'mate {args.command}: interrupted', file=sys.stderr)
        return 130
    except BaseException as exc:
        if not _is_user_error(exc):
            raise
        if _debugging(args):
            traceback.print_exc()
        print(f'mate {args.command}: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':   # `python -m mate.cli`: run the package's module, whose classes the commands import
    from mate.cli import main as package_main

    sys.exit(package_main())
