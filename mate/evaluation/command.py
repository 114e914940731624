"""`mate evaluate`: its options (`add_arguments`) and the command (`run`): play camera agents against target
agents, batched in one vector env whenever both teams have a batched form, else one episode after the other in the
single env, and summarise the episodes (`mate.evaluation.evaluate` plays and summarises; this module reads the
arguments, says what it does and writes the files)."""

from __future__ import annotations

import argparse

from rich.console import Console
from rich.table import Table

from ..cli.arguments import CommandError, non_negative_int, number, positive_int, resolving_arguments

__all__ = ['DEFAULT_GIF', 'DESCRIPTION', 'TEAM_CHOICES', 'add_arguments', 'require_torch_agents', 'run']

console = Console()
TEAM_CHOICES = ('both', 'camera', 'target', 'none')
"""The values of the wrapper flags (`--enhanced-observation TEAM`, ...)."""
DESCRIPTION = ('Play episodes (episode i: a fresh env reset with seed + i, agents seeded alike) and print '
    'mean and std of coverage, transport and returns per team. By default greedy cameras play '
    'greedy targets on MATE-4v8-9 and the first episode is saved as a GIF.')
"""`mate evaluate -h`'s description."""
DEFAULT_GIF = 'mate-evaluate.gif'
"""Where `mate evaluate` saves the first episode when no --save-gif is given (and the render extra is installed)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """`mate evaluate`'s options (no agent, env or torch is imported)."""
    parser.add_argument('--config', '--cfg', default='MATE-4v8-9',
                        help='preset name or YAML/JSON path (default MATE-4v8-9)')
    parser.add_argument('--camera-agent', default='greedy',
                        help='random|naive|greedy|heuristic|mixture|upper-bound, module:Class, checkpoint:PATH or '
                             'pretrained:NAME (upper-bound: a centralised reference that sees the true state)')
    parser.add_argument('--target-agent', default='greedy', help='as --camera-agent')
    parser.add_argument('--camera-kwargs', default='{}', help='JSON keyword arguments of the camera agent')
    parser.add_argument('--target-kwargs', default='{}', help='JSON keyword arguments of the target agent')
    parser.add_argument('--episodes', type=positive_int, default=20, help='episodes to play (default 20)')
    parser.add_argument('--seed', type=non_negative_int, default=0, help='episode i uses seed + i (agents too)')
    parser.add_argument('--max-episode-steps', type=positive_int, default=2000,
                        help='step cap per episode (default 2000)')
    for flag in ('enhanced-observation', 'shared-field-of-view', 'no-communication'):
        parser.add_argument(f'--{flag}', nargs='?', const='both', default='none', choices=TEAM_CHOICES,
                            metavar='TEAM',
                            help=f'add the {flag.replace("-", " ")} wrapper for TEAM (bare flag: both)')
    parser.add_argument('--render-communication', nargs='?', type=positive_int, const=20, default=None,
                        metavar='DURATION',
                        help='draw message arrows in the recorded frames, each for DURATION steps after it was sent '
                             '(bare flag: 20)')
    parser.add_argument('--message-kinds', action='store_true',
                        help='with --render-communication: draw requests orange dashed, replies purple solid and '
                             'broadcasts dashed in the team colour (default: blue camera / red target arrows)')
    parser.add_argument('--no-render', action='store_true', help='record nothing (no GIF, no video)')
    parser.add_argument('--save-gif', default=None, metavar='PATH',
                        help=f'GIF of the first episode (default {DEFAULT_GIF} when the render extra is installed; '
                             'empty string: none)')
    parser.add_argument('--save-video', default=None, metavar='PATH', help='MP4 of the first episode')
    parser.add_argument('--frame-size', type=number(int, minimum=16), default=600,
                        help='recorded frame size in pixels, at least 16 (default 600)')
    parser.add_argument('--no-hud', action='store_true',
                        help='no heads-up line (step, coverage, delivered cargo) in the recorded frames')
    parser.add_argument('--frame-every', type=positive_int, default=4, help='record every N-th step (default 4)')
    parser.add_argument('--json', default=None, metavar='PATH', help='write per-episode results and the summary')
    parser.add_argument('--batched', action='store_true',
                        help='insist on playing every episode at once in one vector env (the default whenever both '
                             'agents have a batched form: random, greedy, upper-bound, checkpoint:PATH, '
                             'pretrained:NAME, and no wrapper is asked for): an error if it cannot. The rule agents '
                             'play the same episodes either way; policies that sample draw from other random streams')
    parser.add_argument('--device', default='cpu',
                        help='where batched policies (checkpoint:, pretrained:) run their forward passes: cpu '
                             '(default), cuda, cuda:N or auto; the games are played on the CPU')
    parser.add_argument('--single-env', action='store_true',
                        help='play the episodes one after the other in the single env with per-agent objects (the '
                             'path of agents without a batched form, and of wrappers)')


def run(args: argparse.Namespace) -> int:
    """Evaluate as `args` (parsed by `add_arguments`) say; 0 when done."""
    from . import evaluate as ev
    from ..messages import Team
    from ..cli.progress import ProgressLine
    from ..envs.registration import make

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
    from ..core.jit import compile_seconds

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
    from ..policies.device import parse_device, resolve_device   # imports no torch

    parse_device(args.device)
    agents = (args.camera_agent, args.target_agent)
    if not any(agent.partition(':')[0] in ('checkpoint', 'pretrained') for agent in agents):
        return 'cpu'
    return resolve_device(args.device)



def require_torch_agents(agents) -> None:
    """A one-line error when trained policies (`checkpoint:PATH`, `pretrained:NAME`) are asked for without torch."""
    from ..cli.extras import require

    for agent in agents:
        if agent.partition(':')[0] in ('checkpoint', 'pretrained'):
            require('train', f'the agent {agent}')


def _recorder(args: argparse.Namespace):
    """The frame recorder of the first episode, or None when nothing is recorded. Without the render extra the
    default GIF is left out with a note, while an explicit --save-gif or --save-video is a one-line error."""
    from . import evaluate as ev
    from ..cli.extras import missing, require

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
        console.print(f'episode results written to {ev.write_json(args.json, settings, results, summary)}',
                      soft_wrap=True)


def _evaluate_batched(args: argparse.Namespace) -> int:
    from . import evaluate as ev
    from ..cli.progress import ProgressLine
    from ..envs.registration import make

    from ..messages import Team

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
    from ..core.jit import compile_seconds

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
    see the true state (`mate.evaluation.evaluate.SEES_TRUE_STATE`: upper-bound)."""
    from . import evaluate as ev
    from .. import wrappers
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


def _summary_title(env, args: argparse.Namespace) -> str:
    """The heading of the summary table: the game, the agents, the episodes."""
    return (f'{env.name}: {args.camera_agent} cameras vs {args.target_agent} targets, '
            f'{args.episodes} episode{"s" if args.episodes > 1 else ""} (seeds {args.seed}..'
            f'{args.seed + args.episodes - 1}, at most {args.max_episode_steps} steps)')


def _print_summary(env, args: argparse.Namespace, summary: list[dict]) -> None:
    # The heading is a line of its own above the table, never wrapped: rich wraps a table's title to the table's
    # width (about 50 columns here), three lines for a long agent name, on a terminal and in a log alike.
    console.print(_summary_title(env, args), soft_wrap=True, highlight=False)
    table = Table()
    for column in ('team', 'metric', 'mean', 'std'):
        table.add_column(column, justify='right' if column in ('mean', 'std') else 'left')
    for row in summary:
        digits = 1 if abs(row['mean']) >= 100 else 4
        table.add_row(row['team'], row['metric'], f"{row['mean']:,.{digits}f}", f"{row['std']:,.{digits}f}")
    console.print(table)


def _save_frames(frames: list, args: argparse.Namespace) -> None:
    from ..tools.video import save_gif, save_video
    fps = max(1, round(30 / args.frame_every))
    if args.save_gif:
        console.print(f'first episode ({len(frames)} frames) saved to {save_gif(frames, args.save_gif, fps=fps)}',
                      soft_wrap=True)
    if args.save_video:
        console.print(f'first episode video saved to {save_video(frames, args.save_video, fps=fps)}', soft_wrap=True)
