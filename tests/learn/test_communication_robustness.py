"""docs/tools/communication_robustness.py: the channel wrappers act on a deployed TarMAC team and the counts add up."""

import json

import pytest

from modules import load_script

robustness = load_script('communication_robustness')



@pytest.fixture(scope='module')
def tarmac_targets(tmp_path_factory):
    from mate.learn.tarmac import TarMACConfig, train

    run = tmp_path_factory.mktemp('tarmac')
    train(TarMACConfig(team='target', config='MATE-2v4-0', num_envs=2, rollout_length=2, steps=4, epochs=1,
                       hidden=(16,), lstm=16, seed=0, threads=1, run_dir=str(run), progress=False))
    return run / 'final.pt'


def test_broadcasts_reach_every_teammate_on_an_ideal_channel_and_none_under_full_dropout(tarmac_targets):
    kwargs = dict(team='target', config='MATE-2v4-0', episodes=1, seed=0, max_steps=30)
    ideal = robustness.score(str(tarmac_targets), channel=('ideal', 0.0), **kwargs)
    lost = robustness.score(str(tarmac_targets), channel=('dropout', 1.0), **kwargs)
    far = robustness.score(str(tarmac_targets), channel=('range', 1e6), **kwargs)
    assert ideal['sent_per_step'] > 0
    assert ideal['delivered_per_step'] == pytest.approx(3 * ideal['sent_per_step'])      # 4 targets: 3 teammates each
    assert lost['sent_per_step'] == ideal['sent_per_step'] and lost['delivered_per_step'] == 0
    assert far['delivered_per_step'] == ideal['delivered_per_step'] and far['mean'] == ideal['mean']


def test_the_script_prints_a_table_writes_json_and_refuses_bad_channels(tarmac_targets, tmp_path, capsys):
    out = tmp_path / 'rows.json'
    assert robustness.main([str(tarmac_targets), '--team', 'target', '--config', 'MATE-2v4-0', '--episodes', '1',
                            '--max-episode-steps', '20', '--dropout', '0', '0.5', '--range', '300',
                            '--json', str(out)]) == 0
    table = capsys.readouterr().out
    assert '| ideal |' in table and '| dropout 0.5 |' in table and '| range 300 |' in table
    rows = json.loads(out.read_text())['rows']
    assert [(r['channel'], r['value']) for r in rows] == [('ideal', 0.0), ('dropout', 0.5), ('range', 300.0)]
    with pytest.raises(SystemExit) as exit_info:
        robustness.main([str(tarmac_targets), '--team', 'target', '--dropout', '1.5'])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    first, *rest = err.strip().splitlines()
    assert 'dropout must be in [0, 1]' in first and len(rest) == 1 and rest[0].endswith(' -h)')
