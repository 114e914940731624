"""The paper's experiments as data: one `Experiment` per figure, each a list of (algorithm, settings) x seeds x budget.

    smoke                a run of the whole pipeline in under a minute (CI)
    smoke-psro           the same for a population experiment
    fig4a-cameras        camera learners on MATE-4v8-9 (flat and HRL), against the greedy targets
    fig4b-cameras-comm   HRL cameras with and without learned communication (TarMAC)
    fig5-targets-comm    target learners with and without learned communication (TarMAC, I2C) on MATE-4v8-0
    fig6-observability   targets with partial and full observability (MATE-2v4-0 and MATE-4v8-0)
    fig7-psro            PSRO-Nash, fictitious self-play and self-play on MATE-2v4-0: exploitability
    fig8-psro-4v8-0      PSRO-Nash on MATE-4v8-0 (>= 10 iterations): exploitability and meta-strategies
    diag-targets-4v8-0   short diagnostic runs of MAPPO targets on MATE-4v8-0 (one change each)
    critic-targets-4v8-0 MAPPO's critic and IPPO's on MATE-4v8-0 targets
    credit-targets-2v4-0 MAPPO targets on MATE-2v4-0 with their own parts of the team reward or the team reward
    witness-rllib-targets   RLlib's PPO beside mate's IPPO, MATE-2v4-0 targets (an independent implementation)
    witness-rllib-cameras   the same for flat MATE-4v8-9 cameras

A training setting is the command line of a `mate train` trainer (the experiment adds the team, the preset, the
budget, the seed, the evaluation protocol and the run directory); a PSRO setting the command line of `mate psro`.
An experiment plays every setting on each of its presets (its tasks: two for Fig. 6, one otherwise).
Every training run is evaluated on held-out seeds (`mate.learn.evaluation`: `eval_every`, `eval_episodes`); the
references (random and greedy, and for cameras the upper-bound controller of `mate.teams`) are played on the same
evaluation seeds. `steps` is the paper's budget per run (10 M decisions for the cooperative runs, its Table 2); a
run may use a smaller one (`mate benchmark run --steps`), which the report states.
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings
from collections.abc import Callable
from pathlib import Path

from ..evaluation.protocol import check_eval_episodes
from .verdicts import ALPHA, runs_for_a_decisive_verdict

__all__ = ['Claim', 'EXPERIMENTS', 'Experiment', 'REFERENCE_NAMES', 'Reference', 'Setting', 'UndecidableClaimWarning',
           'experiment', 'experiment_of', 'reference_label']

REFERENCE_NAMES = ('random', 'greedy', 'upper-bound')
"""The rule teams an experiment may play as references (and name in its claims); a team of the user's is a
`Reference`."""


_BUILDING_THE_PACKAGES = False
"""True while the package's own experiments (`EXPERIMENTS`) are built."""


class UndecidableClaimWarning(UserWarning):
    """An experiment's claim between two settings that its `seeds` runs a side cannot make decisive (`Experiment`
    warns when it is built)."""


def _slug(label: str) -> str:
    """A label in file names: lower case, every run of other characters than letters and digits as one '-'."""
    return re.sub(r'[^a-z0-9]+', '-', label.lower()).strip('-')


def _resolved_call(call: str | None, folder: Path) -> str | None:
    """A call of 'file.py:name' relative to `folder` made absolute; any other as it is."""
    where, _, name = (call or '').rpartition(':')
    if where.endswith('.py') and not Path(where).is_absolute():
        return f'{(folder / where).resolve()}:{name}'
    return call


@dataclasses.dataclass(frozen=True)
class Setting:
    """One algorithm's configuration in an experiment.

    Args:
        label: its name in figures and tables ('HRL-MAPPO', 'MAPPO+TarMAC', ...).
        command: the `mate train` trainer ('mappo', 'ippo', 'mappo-as', 'mappo-lstm', 'tarmac', 'i2c', 'iql', 'qmix',
            'matd3'), 'rllib-ppo' for RLlib's PPO (`mate rllib-train`, the same run files and evaluation protocol), or
            'psro' for a population run; '' for the two kinds below.
        options: further command-line options of the trainer (or of `mate psro`).
        argv: any command line instead (a user's training script), with `{run_dir}`, `{seed}`, ... placeholders; it
            writes the protocol's run files (`mate.benchmark.user`).
        call: a function that trains and returns a policy instead, or 'path/to/file.py:function'
            (`mate.benchmark.user`); a function is stored as the file and name it is defined by.
    """

    label: str
    command: str = ''
    options: tuple[str, ...] = ()
    argv: tuple[str, ...] = ()
    call: str | Callable | None = None

    def __post_init__(self) -> None:
        kinds = [kind for kind, given in (('command', self.command), ('argv', self.argv), ('call', self.call)) if given]
        if len(kinds) != 1:
            raise ValueError(f'setting {self.label!r}: give exactly one of command (a mate trainer), argv (a command '
                             f'line) or call (a training function); got {", ".join(kinds) or "none"}')
        if self.options and not self.command:
            raise ValueError(f'setting {self.label!r}: options go with a mate trainer (command); put them in argv')
        object.__setattr__(self, 'options', tuple(str(o) for o in self.options))
        object.__setattr__(self, 'argv', tuple(str(a) for a in self.argv))
        if callable(self.call):
            object.__setattr__(self, 'call', _reference_of(self.call))

    @property
    def kind(self) -> str:
        """'trainer', 'psro', 'argv' or 'call'."""
        return 'argv' if self.argv else 'call' if self.call else 'psro' if self.command == 'psro' else 'trainer'

    def to_dict(self) -> dict:
        return {key: list(value) if isinstance(value, tuple) else value
                for key, value in dataclasses.asdict(self).items() if value not in ('', (), None)}

    @classmethod
    def from_dict(cls, data: dict) -> Setting:
        """A setting from its mapping (`to_dict`'s, or one of a YAML file's `settings`); ValueError naming a bad key."""
        if not isinstance(data, dict):
            raise ValueError(f'a setting is a mapping (label, and command, argv or call), got {data!r}')
        known = {field.name for field in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f'setting {data.get("label", "?")!r}: unknown key(s) {", ".join(unknown)}; the keys are '
                             f'{", ".join(sorted(known))}')
        data = dict(data)
        for key in ('options', 'argv'):
            if isinstance(data.get(key), str):
                raise ValueError(f'setting {data.get("label", "?")!r}: {key} is a list of strings, got {data[key]!r}')
            data[key] = tuple(data.get(key) or ())
        return cls(**data)

    def resolved_from(self, folder: Path) -> Setting:
        """This setting as the experiment file in `folder` means it: a `call` of 'file.py:name' relative to the
        folder made absolute, and `{here}` in `argv` replaced by the folder (absolute)."""
        folder = Path(folder).resolve()
        argv = tuple(part.replace('{here}', str(folder)) for part in self.argv)
        return dataclasses.replace(self, call=_resolved_call(self.call, folder), argv=argv)

    @property
    def slug(self) -> str:
        """The setting's name in file names: its label in lower case, every run of other characters than letters and
        digits as one '-' ('MAPPO+TarMAC': 'mappo-tarmac', 'MAPPO full obs.': 'mappo-full-obs')."""
        return _slug(self.label)


@dataclasses.dataclass(frozen=True)
class Reference:
    """A team of yours played as a reference, as random and greedy are: once per game, on the experiment's
    evaluation and absolute games against the same opponent, with no budget and no curve; the report shows it beside
    the rule teams, and a claim may name it (`Claim('my PPO beats my rules', 'my PPO', 'my rules')`). A scripted or
    rule-based team enters a comparison this way instead of as a setting run `seeds` times to the same score.

    Args:
        label: its name in the report and in claims (neither a setting's label nor 'random', 'greedy',
            'upper-bound').
        call: the team: a function defined at the top level of a file, or 'path/to/file.py:name' (relative to the
            experiment file) or 'module:name'; either a policy `f(observations (B, N, D)) -> actions (B, N, 2)` or
            a factory `f(num_envs, counts, seed)` of a batched team (three arguments without defaults), told apart
            and scored as the policy a training function returns (`mate.benchmark.user`). Stored as the file and
            name it is defined by.
    """

    label: str
    call: str | Callable

    def __post_init__(self) -> None:
        if not isinstance(self.label, str) or not self.label.strip():
            raise ValueError(f'a reference of yours needs a label (its name in the report and in claims), got '
                             f'{self.label!r}')
        if self.label in REFERENCE_NAMES or _slug(self.label) in REFERENCE_NAMES:
            raise ValueError(f'reference {self.label!r}: the labels {", ".join(REFERENCE_NAMES)} (in any case) are '
                             "the rule teams'; give yours another")
        if callable(self.call):
            object.__setattr__(self, 'call', _reference_of(self.call, 'a reference'))
        if not isinstance(self.call, str) or not self.call.rpartition(':')[0]:
            raise ValueError(f"reference {self.label!r}: call is a function or 'path/to/file.py:name', got "
                             f'{self.call!r}')

    @property
    def slug(self) -> str:
        """Its name in file names (`Setting.slug`)."""
        return _slug(self.label)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> Reference:
        """A reference from its mapping (`to_dict`'s, or an entry of a YAML file's `references`); ValueError naming
        a bad key."""
        if not isinstance(data, dict):
            raise ValueError(f"a reference is {', '.join(REFERENCE_NAMES)} or a mapping (label, call), got {data!r}")
        known = {field.name for field in dataclasses.fields(cls)}
        unknown, missing = sorted(set(data) - known), sorted(known - set(data))
        if unknown or missing:
            what = f'unknown key(s) {", ".join(unknown)}' if unknown else f'missing {", ".join(missing)}'
            raise ValueError(f'reference {data.get("label", "?")!r}: {what}; the keys are {", ".join(sorted(known))}')
        return cls(**data)

    def resolved_from(self, folder: Path) -> Reference:
        """This reference as the experiment file in `folder` means it (`Setting.resolved_from`)."""
        return dataclasses.replace(self, call=_resolved_call(self.call, Path(folder).resolve()))


def reference_label(reference: str | Reference) -> str:
    """The name a reference goes by in jobs, the report and claims: a rule team's name, or a `Reference`'s label."""
    return reference if isinstance(reference, str) else reference.label


@dataclasses.dataclass(frozen=True)
class Claim:
    """One comparison the paper makes, which the report judges: `better` scores above `worse` (for population
    experiments: a lower final exploitability); or, with `kind='agree'`, two settings that should score alike.

    Args:
        text: the claim in words.
        better: a setting label of the experiment, or a reference it plays (its `references`).
        worse: the same, for the side claimed to score lower.
        preset: the game it is about (None: each of the experiment's).
        kind: 'better', or 'agree' (two settings).
        margin: for an agreement claim, the largest difference of the settings' mean scores (in the metric's units)
            that still counts as agreeing; without one, no test can show agreement and the verdict reads *no
            difference detected* at best.

    The verdict (`mate.benchmark.verdicts`): decisive only where the 95 % interval and a test with a controlled
    false-positive rate agree at 5 %, after Holm's correction over the experiment's claims. Between two settings:
    the interval of the probability of improvement P(better > worse) against 1/2 and the exact Mann-Whitney
    permutation test (*confirmed*, *refuted*, *unresolved*; 3 runs a side can never be decisive); between a setting
    and a reference: the paired bootstrap interval of the difference on the same held-out episodes and a t-test whose
    error counts the runs' and the episodes' spread once each; a test whose statistic points the other way from the
    interval leaves the claim *unresolved*; agreement: *equivalent* by two one-sided tests within `margin`,
    *differ*, or *no difference detected*.
    """

    text: str
    better: str
    worse: str
    preset: str | None = None
    kind: str = 'better'
    margin: float | None = None

    def __post_init__(self) -> None:
        if self.margin is not None and (self.kind != 'agree' or not self.margin > 0):
            raise ValueError(f"a claim's margin is a positive number, for kind='agree' only, got {self.margin!r} "
                             f'(kind {self.kind!r})')
        if self.kind not in ('better', 'agree'):
            raise ValueError(f"a claim's kind is 'better' or 'agree', got {self.kind!r}")


@dataclasses.dataclass(frozen=True)
class Experiment:
    """One figure of the paper as runs (module docstring).

    Args:
        name: the experiment's name (`mate benchmark run NAME`).
        figure: what of the paper it reproduces.
        team: the trained team ('camera' or 'target'; PSRO trains both: 'both').
        presets: the games (tasks) every setting plays.
        settings: the algorithms and their options.
        steps: decision steps per training run (PSRO: per best response).
        eval_every: decision steps between evaluations at the experiment's budget (`eval_interval`: at a smaller one);
            eval_episodes: episodes per evaluation.
        horizon: env steps per training and evaluation episode (None: the trainer's, 500 decisions).
        references: teams played on the evaluation seeds, once per game: the rule teams 'random', 'greedy',
            'upper-bound', and teams of yours as `Reference(label, call=...)` (in a YAML file, a mapping `{label,
            call}`).
        iterations: PSRO iterations (population experiments only).
        seeds: runs per (setting, preset) unless `mate benchmark run --seeds` says otherwise.
        claim: the paper's claim the experiment tests, in a sentence.
        claims: that claim as comparisons the report judges.
        source: 'paper' for the package's experiments (their claims are the paper's, or mate's diagnostics of
            them), 'user' for an experiment of the user's file (`mate.benchmark.user`).

    Built, it warns (`UndecidableClaimWarning`) for each claim between two settings that `seeds` runs a side can never
    make decisive: the exact Mann-Whitney test needs 4 runs a side to reach 5 % at all, and more under Holm's
    correction over the experiment's claims (`mate.benchmark.verdicts.runs_for_a_decisive_verdict`).
    """

    name: str
    figure: str
    team: str
    presets: tuple[str, ...]
    settings: tuple[Setting, ...]
    steps: int
    eval_every: int = 500_000
    eval_episodes: int = 32
    horizon: int | None = None
    references: tuple[str | Reference, ...] = ('random', 'greedy')
    iterations: int = 0
    seeds: int = 5
    claim: str = ''
    claims: tuple[Claim, ...] = ()
    source: str = 'user'

    def __post_init__(self) -> None:
        if self.team not in ('camera', 'target', 'both'):
            raise ValueError(f"experiment {self.name!r}: team is 'camera', 'target' or 'both', got {self.team!r}")
        if not self.settings or not self.presets:
            raise ValueError(f'experiment {self.name!r}: it needs at least one setting and one preset')
        object.__setattr__(self, 'settings', tuple(self.settings))
        for key in ('presets', 'references'):        # a single name (a YAML file's `presets: MATE-2v4-0`) is one
            value = getattr(self, key)
            object.__setattr__(self, key, (value,) if isinstance(value, (str, Reference, dict)) else tuple(value))
        try:
            object.__setattr__(self, 'references', tuple(Reference.from_dict(r) if isinstance(r, dict) else r
                                                         for r in self.references))
        except ValueError as exc:
            raise ValueError(f'experiment {self.name!r}: {exc}') from None
        object.__setattr__(self, 'claims', tuple(self.claims))
        self._check_counts()
        labels = [setting.label for setting in self.settings]
        twice = sorted({label for label in labels if labels.count(label) > 1})
        if twice:
            raise ValueError(f'experiment {self.name!r}: setting labels must differ; {twice[0]!r} is used twice')
        bad = [r for r in self.references if not isinstance(r, Reference) and r not in REFERENCE_NAMES]
        if bad:
            raise ValueError(f'experiment {self.name!r}: unknown reference {bad[0]!r}; references are '
                             f'{", ".join(REFERENCE_NAMES)}, or a team of yours as Reference(label, call=...)')
        if self.team == 'target' and 'upper-bound' in self.references:
            raise ValueError(f"experiment {self.name!r}: 'upper-bound' is a camera controller; a target experiment's "
                             "references are random and greedy")
        names = [reference_label(r) for r in self.references]
        slugs = [_slug(name) for name in names]
        clash = next((name for name, slug in zip(names, slugs) if name in labels or slugs.count(slug) > 1), None)
        if clash is not None:
            raise ValueError(f'experiment {self.name!r}: reference {clash!r} is named twice (as a setting or another '
                             'reference, in file names lower case); every reference and setting needs its own label')
        played = () if self.population else tuple(names)         # a population experiment plays no references
        for claim in self.claims:
            for side in (claim.better, claim.worse):
                if side not in (*labels, *played):
                    raise ValueError(f'experiment {self.name!r}, claim {claim.text!r}: {side!r} is neither a setting '
                                     f'({", ".join(labels)}) nor a reference it plays ({", ".join(played) or "none"})')
            if claim.preset is not None and claim.preset not in self.presets:
                raise ValueError(f'experiment {self.name!r}, claim {claim.text!r}: preset {claim.preset!r} is not one '
                                 f'of its games ({", ".join(self.presets)})')
        self._warn_undecidable(labels)

    def _warn_undecidable(self, labels: list[str]) -> None:
        """An `UndecidableClaimWarning` for each claim that one setting beats another which `seeds` runs a side can
        never make decisive: the exact Mann-Whitney test's smallest two-sided p-value, 2 / C(2 n, n), must be below
        `ALPHA` (n >= 4), and Holm's correction multiplies the smallest of the experiment's k tests by k (n such that
        2 k / C(2 n, n) < ALPHA, whatever the other claims' tests give)."""
        if self.source == 'paper' or _BUILDING_THE_PACKAGES:
            return
        tests = sum(len(self.presets) if claim.preset is None else 1 for claim in self.claims)
        alone, anyway = runs_for_a_decisive_verdict(ALPHA), runs_for_a_decisive_verdict(ALPHA / max(tests, 1))
        for claim in self.claims:
            if claim.kind != 'better' or claim.better not in labels or claim.worse not in labels:
                continue
            if self.seeds >= anyway:
                continue
            smallest = 2 / math.comb(2 * self.seeds, self.seeds)
            if self.seeds < alone:
                why = (f'at seeds={self.seeds} a claim between two settings can never be decisive (the exact '
                       f'Mann-Whitney test\'s smallest p at {self.seeds} vs {self.seeds} runs is {smallest:.2g}, not '
                       f'below {ALPHA:g})')
            else:
                why = (f'at seeds={self.seeds} it is decisive only if the other claims\' tests are significant first '
                       f'(Holm\'s correction over the experiment\'s {tests} tests multiplies the smallest p-value, '
                       f'{smallest:.2g} at {self.seeds} vs {self.seeds} runs, by {tests})')
            warnings.warn(f'experiment {self.name!r}, claim {claim.text!r}: {why}; {anyway} seeds or more can '
                          f'decide it (the experiment\'s seeds={anyway}, or mate benchmark run --seeds 0-{anyway - 1})',
                          UndecidableClaimWarning, stacklevel=4)

    def _check_counts(self) -> None:
        """ValueError unless the budget and counts are positive integers (`horizon` and, for a population
        experiment, `iterations` may be left out) and `eval_episodes` is at most
        `mate.evaluation.protocol.MAX_EVAL_EPISODES` (its absolute metric's seeds stay in their range)."""
        counts = dict(steps=self.steps, eval_every=self.eval_every, eval_episodes=self.eval_episodes, seeds=self.seeds)
        counts.update({} if self.horizon is None else dict(horizon=self.horizon))
        counts.update(dict(iterations=self.iterations) if self.population else {})
        for key, value in counts.items():
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f'experiment {self.name!r}: {key} is a positive whole number, got {value!r}')
        try:
            check_eval_episodes(self.eval_episodes)
        except ValueError as exc:
            raise ValueError(f'experiment {self.name!r}: {exc}') from None

    def to_dict(self) -> dict:
        """The experiment as plain data (what a benchmark directory's manifest keeps; `from_dict` reads it)."""
        data = {field.name: getattr(self, field.name) for field in dataclasses.fields(self)}
        data['settings'] = [setting.to_dict() for setting in self.settings]
        data['claims'] = [dataclasses.asdict(claim) for claim in self.claims]
        data['presets'] = list(self.presets)
        data['references'] = [r if isinstance(r, str) else r.to_dict() for r in self.references]
        return data

    @classmethod
    def from_dict(cls, data: dict) -> Experiment:
        """An experiment from its mapping (`to_dict`'s, or a YAML file's); ValueError naming a bad key."""
        known = {field.name for field in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f'unknown experiment key(s) {", ".join(unknown)}; the keys are {", ".join(sorted(known))}')
        data = dict(data)
        try:
            data['settings'] = tuple(Setting.from_dict(s) for s in data.get('settings') or ())
            data['claims'] = tuple(Claim(**c) for c in data.get('claims') or ())
            return cls(**data)
        except TypeError as exc:
            raise ValueError(f'experiment {data.get("name", "?")!r}: {exc}') from None

    def resolved_from(self, path: Path) -> Experiment:
        """This experiment as its file `path` means it (`Setting.resolved_from` the file's folder)."""
        folder = Path(path).resolve().parent
        with warnings.catch_warnings():         # the same claims and seeds: said when it was built
            warnings.simplefilter('ignore', UndecidableClaimWarning)
            return dataclasses.replace(self, settings=tuple(s.resolved_from(folder) for s in self.settings),
                                       references=tuple(r if isinstance(r, str) else r.resolved_from(folder)
                                                        for r in self.references))

    @property
    def own_references(self) -> tuple[Reference, ...]:
        """The references that are teams of the user's (`Reference`), in order."""
        return tuple(r for r in self.references if isinstance(r, Reference))

    @property
    def population(self) -> bool:
        return any(setting.command == 'psro' for setting in self.settings)

    def eval_interval(self, steps: int) -> int:
        """Decision steps between evaluations in a run of `steps` decisions: `eval_every` at the experiment's budget
        or above; a smaller budget (`mate benchmark run --steps`) evaluates at least 4 times (every steps // 4, when
        that is sooner), so that its curves keep a shape."""
        if steps >= self.steps:
            return self.eval_every
        return max(1, min(self.eval_every, steps // 4))

    def task(self, preset: str) -> str:
        """The task's name in tables and results files: the preset and the trained team ('MATE-4v8-9 cameras')."""
        return preset if self.population else f'{preset} {self.team}s'


CAMERA_REFERENCES = ('random', 'greedy', 'upper-bound')
RECIPE = ('--entropy-schedule', '[[0, 0.03], [2000000, 0.01], [4000000, 0]]')
"""The HRL-MAPPO recipe of the shipped camera policy (a larger entropy bonus than the defaults)."""
OWN = ('--credit', 'own')
"""The target learners of the figures' experiments are rewarded with each target's own part of the team reward (its
tracking penalty and deliveries, which sum to the team's): with the team reward alone, MAPPO targets on MATE-4v8-0
score -0.075, -0.060 and 0.133 over 1 M decisions in three seeds (random -0.09), with their own parts 0.253, 0.249
and 0.262 (greedy 0.33; `diag-targets-4v8-0`, docs/results.md). The paper's learners used the team reward. On
MATE-2v4-0 the team reward is the better one (`credit-targets-2v4-0`); the figures keep one setting for both games."""
OWN_PSRO = ('--target-credit', 'own')
"""The population experiments' target best responses are rewarded as the figures' target learners are (`OWN`): the
team reward the paper used leaves MAPPO targets on the floor of MATE-4v8-0, and a population whose target best
responses cannot learn would measure the cameras alone."""
PAPER_PPO = ('--paper', '--epochs', '16', '--gae-lambda', '1.0')
"""MAPPO with the paper's RLlib PPO hyper-parameters where ours differ (docs/training.md, "Network options"): `--paper`
(adaptive KL penalty from 0.2, its learning-rate steps and entropy ramps stretched over 10 M decisions), 16 epochs, GAE
lambda 1."""
AS_IPPO = ('--epochs', '4', '--minibatch-size', '1600', '--gae-lambda', '0.95', '--kl-coeff', '0', '--max-grad-norm',
           '10', '--lr-schedule', '[[0, 0.0005], [1499999, 0.0005], [1500000, 0.0002], [2999999, 0.0002], '
           '[3000000, 0.0001]]', '--entropy-schedule', '[[0, 0.01], [1000000, 0.001], [3000000, 0]]',
           '--num-cpus', '1')
"""`mate rllib-train` options that give RLlib's PPO the hyper-parameters of `mate train ippo`'s defaults: 4 epochs,
4 minibatches of the 64 x 25-decision batch of 4 agents (1,600 rows each), GAE lambda 0.95, no KL penalty, gradients
clipped at norm 10, the same learning-rate steps (as near-vertical ramps: RLlib interpolates) and entropy ramps.
What stays different: RLlib learns its values on raw returns (IPPO normalises them) and clips no value error."""
WITNESS_CLAIM = 'RLlib\'s PPO (the engine of the paper\'s authors) and mate\'s IPPO score alike at equal decisions'


def _witness(team: str, preset: str, task: str, references: tuple[str, ...]) -> Experiment:
    """The RLlib witness on one team's task: mate's IPPO, RLlib's PPO with IPPO's settings and with the paper's, at
    equal decisions; the claim that the first two agree."""
    return Experiment(
        f'witness-rllib-{team}s', f"a witness: RLlib's PPO beside IPPO on {task}", team, (preset,),
        (Setting('IPPO', 'ippo'), Setting('RLlib PPO', 'rllib-ppo', AS_IPPO),
         Setting('RLlib PPO (paper settings)', 'rllib-ppo', ('--num-cpus', '1'))),
        steps=2_000_000, eval_every=250_000, references=references, seeds=3, claim=WITNESS_CLAIM,
        claims=(Claim("RLlib PPO with IPPO's settings scores as IPPO", 'RLlib PPO', 'IPPO', kind='agree'),))


_BUILDING_THE_PACKAGES = True       # no UndecidableClaimWarning for them: their docs say what their seeds decide
EXPERIMENTS = {experiment.name: dataclasses.replace(experiment, source='paper') for experiment in (
    Experiment(
        'smoke', 'the whole pipeline in seconds (CI)', 'camera', ('MATE-2v4-0',),
        (Setting('MAPPO', 'mappo', ('--num-envs', '4', '--rollout-length', '10', '--hidden', '16', '16')),
         Setting('IPPO', 'ippo', ('--num-envs', '4', '--rollout-length', '10', '--hidden', '16', '16'))),
        steps=200, eval_every=80, eval_episodes=3, horizon=50, references=CAMERA_REFERENCES, seeds=3,
        claim='the pipeline runs end to end',
        claims=(Claim('(pipeline check) MAPPO beats IPPO', 'MAPPO', 'IPPO'),
                Claim('(pipeline check) MAPPO beats the random cameras', 'MAPPO', 'random'),
                Claim('(pipeline check) MAPPO and IPPO agree', 'MAPPO', 'IPPO', kind='agree'))),
    Experiment(
        'smoke-psro', 'the population pipeline in seconds (CI)', 'both', ('MATE-2v4-0',),
        (Setting('PSRO-Nash', 'psro', ('--solver', 'nash', '--num-envs', '4', '--eval-episodes', '2',
                                       '--eval-steps', '20')),),
        steps=150, iterations=1, seeds=2, claim='the population pipeline runs end to end'),
    Experiment(
        'fig4a-cameras', 'Fig. 4 (left): camera learners against greedy targets', 'camera', ('MATE-4v8-9',),
        (Setting('MAPPO', 'mappo'), Setting('IPPO', 'ippo'), Setting('HRL-MAPPO', 'mappo', ('--hrl', *RECIPE)),
         Setting('HRL-IPPO', 'ippo', ('--hrl', *RECIPE)), Setting('HRL-IQL', 'iql', ('--hrl',)),
         Setting('HRL-QMIX', 'qmix', ('--hrl',)), Setting('MA-TD3', 'matd3')),
        steps=10_000_000, references=CAMERA_REFERENCES,
        claim='HRL cameras learn faster and cover more than flat ones; the learned cameras beat the greedy rules',
        claims=(Claim('HRL-MAPPO cameras cover more than flat MAPPO ones', 'HRL-MAPPO', 'MAPPO'),
                Claim('HRL-IPPO cameras cover more than flat IPPO ones', 'HRL-IPPO', 'IPPO'),
                Claim('HRL-MAPPO cameras cover more than the greedy cameras', 'HRL-MAPPO', 'greedy'))),
    Experiment(
        'fig4b-cameras-comm', 'Fig. 4 (right): HRL cameras with learned communication', 'camera', ('MATE-4v8-9',),
        (Setting('HRL-MAPPO', 'mappo', ('--hrl', *RECIPE)),
         Setting('HRL-MAPPO+TarMAC', 'tarmac', ('--hrl', *RECIPE))),
        steps=10_000_000, references=CAMERA_REFERENCES,
        claim='learned communication helps the cameras little',
        claims=(Claim('HRL-MAPPO+TarMAC cameras cover more than HRL-MAPPO ones', 'HRL-MAPPO+TarMAC', 'HRL-MAPPO'),)),
    Experiment(
        'fig5-targets-comm', 'Fig. 5: target learners with learned communication', 'target', ('MATE-4v8-0',),
        (Setting('MAPPO', 'mappo', OWN), Setting('IPPO', 'ippo', OWN), Setting('MAPPO+TarMAC', 'tarmac', OWN),
         Setting('IPPO+TarMAC', 'tarmac', ('--critic', 'local', *OWN)), Setting('MAPPO+I2C', 'i2c', OWN)),
        steps=10_000_000,
        claim='communication helps the targets; MAPPO+I2C is best',
        claims=(Claim('MAPPO targets score above the greedy targets', 'MAPPO', 'greedy'),
                Claim('TarMAC helps MAPPO targets', 'MAPPO+TarMAC', 'MAPPO'),
                Claim('TarMAC helps IPPO targets', 'IPPO+TarMAC', 'IPPO'),
                Claim('I2C helps MAPPO targets', 'MAPPO+I2C', 'MAPPO'),
                Claim('MAPPO+I2C beats MAPPO+TarMAC', 'MAPPO+I2C', 'MAPPO+TarMAC'))),
    Experiment(
        'fig6-observability', 'Fig. 6: targets with partial and full observability', 'target',
        ('MATE-2v4-0', 'MATE-4v8-0'),
        (Setting('MAPPO', 'mappo', OWN), Setting('MAPPO full obs.', 'mappo', ('--full-observability', *OWN))),
        steps=10_000_000,
        claim='partial observability costs the targets about 0.1 of normalised return',
        claims=(Claim('full observability helps the targets', 'MAPPO full obs.', 'MAPPO'),
                Claim('MAPPO targets learn off the floor (above the random targets)', 'MAPPO', 'random'))),
    Experiment(
        'diag-targets-4v8-0', 'diagnostics: why MAPPO targets stay on the floor on MATE-4v8-0 (short runs)', 'target',
        ('MATE-4v8-0',),
        (Setting('MAPPO', 'mappo'), Setting('full obs.', 'mappo', ('--full-observability',)),
         Setting('own credit', 'mappo', ('--credit', 'own')),
         Setting('entropy 0.03', 'mappo', ('--entropy-schedule', '[[0, 0.03]]')),
         Setting('recurrent', 'mappo-lstm'),
         Setting('hold 5', 'mappo', ('--frame-skip', '5')),
         Setting('gamma 0.995', 'mappo', ('--gamma', '0.995')),
         Setting('16 envs', 'mappo', ('--num-envs', '16')),
         Setting('hidden 64', 'mappo', ('--hidden', '64', '64')),
         Setting('paper settings', 'mappo', PAPER_PPO)),     # last: 16 epochs make it the slowest
        steps=1_000_000, eval_every=250_000, eval_episodes=16, seeds=2,
        claim='one of these settings lifts MAPPO targets off the floor',
        claims=(Claim('MAPPO targets learn off the floor (above the random targets)', 'MAPPO', 'random'),
                Claim('full observability helps', 'full obs.', 'MAPPO'),
                Claim("the paper's PPO settings help", 'paper settings', 'MAPPO'),
                Claim("each target's own part of the team reward helps", 'own credit', 'MAPPO'),
                Claim('a larger entropy bonus helps', 'entropy 0.03', 'MAPPO'),
                Claim('memory (the paper\'s recurrent actor and critic) helps', 'recurrent', 'MAPPO'),
                Claim('a 5-step hold helps', 'hold 5', 'MAPPO'),
                Claim('a longer discount horizon helps', 'gamma 0.995', 'MAPPO'),
                Claim('fewer envs (more updates per decision) help', '16 envs', 'MAPPO'),
                Claim('a narrower network helps', 'hidden 64', 'MAPPO'))),
    Experiment(
        'critic-targets-4v8-0', "diagnostics: MAPPO's critic and IPPO's on MATE-4v8-0 targets (own credit)", 'target',
        ('MATE-4v8-0',),
        (Setting('MAPPO', 'mappo', OWN), Setting('IPPO', 'ippo', OWN), Setting('MAPPO-AS', 'mappo-as', OWN)),
        steps=10_000_000,        # fig5-targets-comm's budget and evaluations: its MAPPO and IPPO runs are reused
        claim="IPPO's targets beat MAPPO's because MAPPO's critic, on the global state alone, fits each target's "
              'own return less well',
        claims=(Claim("the agent's own observation beside the state helps MAPPO's critic", 'MAPPO-AS', 'MAPPO'),
                Claim('MAPPO-AS targets score above the greedy targets', 'MAPPO-AS', 'greedy'),
                Claim('MAPPO-AS and IPPO targets agree', 'MAPPO-AS', 'IPPO', kind='agree'))),
    Experiment(
        'credit-targets-2v4-0', "diagnostics: MAPPO targets on MATE-2v4-0 with their own rewards or the team's",
        'target', ('MATE-2v4-0',),
        (Setting('MAPPO', 'mappo', OWN), Setting('MAPPO team reward', 'mappo'),
         Setting('MAPPO full obs. team reward', 'mappo', ('--full-observability',))),
        steps=10_000_000,        # fig6-observability's budget and evaluations: its MAPPO runs are reused
        claim="each target's own part of the team reward, which lifts MAPPO targets off the floor of MATE-4v8-0, "
              'helps them on MATE-2v4-0 too',
        claims=(Claim("each target's own part of the team reward helps on MATE-2v4-0", 'MAPPO', 'MAPPO team reward'),
                Claim('MAPPO targets with the team reward score above the greedy targets', 'MAPPO team reward',
                      'greedy'),
                Claim('full observability helps the targets with the team reward (Fig. 6 with the paper\'s reward)',
                      'MAPPO full obs. team reward', 'MAPPO team reward'))),
    _witness('target', 'MATE-2v4-0', 'MATE-2v4-0 targets', references=('random', 'greedy')),
    _witness('camera', 'MATE-4v8-9', 'flat MATE-4v8-9 cameras', references=CAMERA_REFERENCES),
    Experiment(
        'fig7-psro', 'Fig. 7: exploitability of PSRO-Nash, FSP and SP', 'both', ('MATE-2v4-0',),
        (Setting('PSRO-Nash', 'psro', ('--solver', 'nash', *OWN_PSRO)),
         Setting('FSP', 'psro', ('--solver', 'uniform', *OWN_PSRO)),
         Setting('SP', 'psro', ('--solver', 'last', *OWN_PSRO))),
        steps=100_000, iterations=10,
        claim='PSRO-Nash and SP reach less exploitable populations; FSP decreases slowly',
        claims=(Claim('PSRO-Nash ends less exploitable than FSP', 'PSRO-Nash', 'FSP'),
                Claim('SP ends less exploitable than FSP', 'SP', 'FSP'),
                # not a claim of Fig. 7 (whose text groups PSRO-Nash with SP) but the paper's reason for PSRO: self-play
                # "may fail to converge" without a diverse population (related work, section 2)
                Claim('PSRO-Nash ends less exploitable than SP', 'PSRO-Nash', 'SP'))),
    Experiment(
        'fig8-psro-4v8-0', 'Fig. 8: PSRO-Nash on MATE-4v8-0', 'both', ('MATE-4v8-0',),
        (Setting('PSRO-Nash', 'psro', ('--solver', 'nash', *OWN_PSRO)),),
        steps=100_000, iterations=10,
        claim='both teams adapt; the Nash meta-strategies spread over several policies'),
)}
"""Every experiment, by name."""
_BUILDING_THE_PACKAGES = False


def experiment(name: str) -> Experiment:
    """The experiment `name`; ValueError listing the experiments otherwise."""
    if name not in EXPERIMENTS:
        raise ValueError(f'unknown experiment {name!r}; experiments: {", ".join(EXPERIMENTS)}, or a file of yours '
                         '(.py, .yaml, .json)')
    return EXPERIMENTS[name]


def experiment_of(manifest: dict) -> Experiment:
    """The experiment of a benchmark directory's manifest (`mate.benchmark.directory.read_manifest`): the definition
    it keeps (format 'mate.benchmark/2'), or for a directory written before manifests kept it ('mate.benchmark/1')
    the package's experiment of its name; ValueError otherwise."""
    if manifest.get('definition'):
        with warnings.catch_warnings():         # said when the experiment was built; the report's verdicts say more
            warnings.simplefilter('ignore', UndecidableClaimWarning)
            return Experiment.from_dict(manifest['definition'])
    if manifest['experiment'] not in EXPERIMENTS:
        raise ValueError(f"the manifest names the experiment {manifest['experiment']!r} without its definition (an old "
                         f"manifest, format {manifest.get('format')!r}) and the package has none of that name")
    return EXPERIMENTS[manifest['experiment']]


def _reference_of(function: Callable, what: str = 'a call setting') -> str:
    """'path/to/file.py:name' of a function defined at the top level of a file."""
    import inspect

    try:
        file = inspect.getsourcefile(function)
    except TypeError:
        file = None
    name = getattr(function, '__name__', '')
    if not file or not name or name == '<lambda>' or getattr(function, '__qualname__', name) != name:
        raise ValueError(f'{what} needs a function defined at the top level of a file (def name(...)), got '
                         f'{function!r}')
    return f'{Path(file).resolve()}:{name}'
