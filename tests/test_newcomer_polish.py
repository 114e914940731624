"""What a newcomer tripped on: a space that floods the terminal, a team sample without a shape, an argument error that
does not name the subcommand, a literal '%%' in help, a first run's speed that hides its compile time."""

from __future__ import annotations

import types

import numpy as np
import pytest

import mate
from mate.cli.main import build_parser, main


def test_the_spaces_print_in_a_line_or_two():
    env = mate.make('MATE-4v8-9-v0')
    text = repr(env.observation_space)
    assert len(text) < 300 and '(126,)' in text and 'x 4' in text and 'x 8' in text
    assert env.observation_space[0][0].low.shape == (126,)          # the bounds are all still there
    assert len(repr(env.action_space)) < 200


def test_a_team_sample_reads_as_its_array():
    env = mate.make('MATE-4v8-9-v0')
    env.action_space.seed(0)
    cameras, targets = env.action_space.sample()
    assert cameras.shape == (4, 2) and targets.shape == (8, 2) and cameras.dtype == np.float64
    np.testing.assert_array_equal(np.asarray(cameras), np.stack(cameras))
    assert np.asarray(cameras, dtype=np.float32).dtype == np.float32
    assert len(cameras) == 4                                          # still the tuple of per-agent samples


@pytest.mark.parametrize('argv, said', [
    (['evaluate', '--episdoes', '3'], 'mate evaluate: error: unrecognized arguments: --episdoes 3\n'
                                      '(see mate evaluate -h)'),
    (['benchmark', 'report', 'x', '--bogus'], 'mate benchmark report: error: unrecognized arguments: --bogus'),
])
def test_an_unknown_option_is_named_by_its_subcommand(argv, said, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2 and said in capsys.readouterr().err


def test_help_shows_percent_signs_once(capsys):
    parser = build_parser()
    with pytest.raises(SystemExit):
        parser.parse_args(['benchmark', '-h'])
    out = capsys.readouterr().out
    assert '95 % bootstrap' in out and '%%' not in out


def test_compile_time_is_counted_once_for_nested_compilations(monkeypatch):
    from mate.core import jit

    notice = jit._CompileNotice()
    clock = iter([10.0, 13.5, 20.0, 21.0])
    monkeypatch.setattr(jit.time, 'perf_counter', lambda: next(clock))
    monkeypatch.setattr(jit, 'compile_notice_wanted', lambda: False)

    def event(module):
        return types.SimpleNamespace(data={'dispatcher': types.SimpleNamespace(
            py_func=types.SimpleNamespace(__module__=module))})

    outer, inner, other = event('mate.core.engine'), event('mate.core.cargo'), event('numpy.something')
    notice.on_start(outer)
    notice.on_start(inner)                  # compiled while the outer one compiles: not counted twice
    notice.on_start(other)                  # not mate's
    notice.on_end(other)
    notice.on_end(inner)
    notice.on_end(outer)                    # 10.0 -> 13.5
    notice.on_start(outer)
    notice.on_end(outer)                    # 20.0 -> 21.0
    assert notice.seconds == pytest.approx(4.5)
