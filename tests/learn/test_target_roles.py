"""docs/tools/target_roles.py: per-target features against a recorded trajectory, the role analysis on synthetic
data, RenderCommunication(kinds=True) frames, and one-line errors."""


import numpy as np
import pytest

import mate
from mate.policies.policy import PolicyTargetAgent, load_policy
from mate.envs.render import Renderer
from modules import load_script

roles_script = load_script('target_roles')
NAMES = roles_script.NAMES



def _record(config, target_factory, steps, seed=0, renderers=None):
    """Greedy cameras vs `target_factory` agents through the kinds-counting wrapper: the script's features of
    the episode, the target infos of every step, and (with `renderers`) per step the frames with and without
    the communication callback and whether any teammate-to-teammate message was delivered."""
    env = mate.RenderCommunication(mate.make('MultiAgentTracking-v0', config=config), duration=1, kinds=True)
    base = env.unwrapped
    (camera_obs, target_obs), _ = env.reset(seed=seed)
    cameras = mate.GreedyCameraAgent(seed=seed).spawn(base.num_cameras)
    targets = target_factory(seed=seed).spawn(base.num_targets)
    mate.group_reset(cameras, camera_obs)
    mate.group_reset(targets, target_obs)
    recorder = roles_script.EpisodeRecorder(getattr(targets[0], 'frame_skip', 1))
    recorder(env, 0, None)
    camera_infos = target_infos = None
    infos, frames = [], []
    for step in range(1, steps + 1):
        action = (mate.group_step(env, cameras, camera_obs, camera_infos),
                  mate.group_step(env, targets, target_obs, target_infos))
        (camera_obs, target_obs), _, terminated, truncated, (camera_infos, target_infos) = env.step(action)
        recorder(env, step, action)
        infos.append(target_infos)
        if renderers is not None:
            with_arrows = renderers[0].render(base)
            callback = base.render_callbacks.pop('communication')
            without = renderers[1].render(base)
            base.add_render_callback('communication', callback)
            talked = any(m.sender != m.recipient for team_infos in (camera_infos, target_infos)
                         for info in team_infos for m in info['messages'])
            frames.append((with_arrows, without, talked))
        if terminated or truncated:
            break
    return recorder.features(), infos, frames, recorder.steps


def test_features_match_the_infos_of_a_recorded_trajectory():
    features, infos, _, steps = _record('MATE-4v8-0', mate.GreedyTargetAgent, 300)
    f = dict(zip(NAMES, features.T))
    # coverage rate of a step = share of targets seen: its mean over steps is the mean tracked share
    assert np.isclose(f['tracked'].mean(), np.mean([i[0]['coverage_rate'] for i in infos]))
    assert 0 < f['tracked'].mean() < 1
    assert f['delivered_units'].sum() == infos[-1][0]['num_delivered_cargoes'] > 0
    assert (f['deliveries'] <= f['delivered_units']).all() and f['deliveries'].sum() > 0
    assert (f['occluded'] == 0).all()                                        # MATE-4v8-0 has no obstacles
    assert (f['camera_distance'] > 0).all() and (0 <= f['loaded']).all() and (f['loaded'] <= 1).all()
    # greedy targets broadcast their news: the copies each target received from teammates, read in the infos
    received = np.array([sum(m.broadcasting and m.sender != t for i in infos for m in i[t]['messages'])
                         for t in range(8)])
    assert np.allclose(f['broadcasts_received'] * steps, received) and received.sum() > 0
    sent = np.array([sum(m.broadcasting and m.sender == t == m.recipient for i in infos for m in i[t]['messages'])
                     for t in range(8)])
    assert np.allclose(f['broadcasts_sent'] * steps, sent)
    assert (f['requests_sent'] == 0).all() and (f['replies_received'] == 0).all()


def test_play_measures_the_same_episode():
    per_episode = roles_script.play('MATE-4v8-0', 'greedy', episodes=1, max_steps=60)
    features, *_ = _record('MATE-4v8-0', mate.GreedyTargetAgent, 60)
    assert per_episode.shape == (1, 8, len(NAMES)) and np.allclose(per_episode[0], features)


@pytest.fixture(scope='module')
def i2c_targets(tmp_path_factory):
    """A nearly untrained I2C policy of the 4 targets of MATE-2v4-0 (one iteration of tiny nets)."""
    from mate.learn.i2c import I2CConfig, train

    run = tmp_path_factory.mktemp('i2c-roles')
    train(I2CConfig(team='target', config='MATE-2v4-0', num_envs=2, rollout_length=2, steps=4, epochs=1, hidden=(16,),
                    lstm=16, seed=0, threads=1, influence_samples=6, run_dir=str(run), progress=False))
    return run / 'final.pt'


def test_i2c_requests_and_replies_are_counted_and_drawn_apart(i2c_targets):
    policy = load_policy(i2c_targets, 'target')
    factory = lambda seed: PolicyTargetAgent(policy, seed=seed, deterministic=True)  # noqa: E731
    renderers = Renderer('rgb_array', window_size=600), Renderer('rgb_array', window_size=600)
    features, infos, frames, steps = _record('MATE-2v4-0', factory, 24, renderers=renderers)
    f = dict(zip(NAMES, features.T))
    decisions = steps / policy.spec.frame_skip
    # requests are {'i2c': None}, replies carry an observation: classified by content, independently of rounds
    requests = np.array([sum(m.content['i2c'] is None for i in infos for m in i[t]['messages']) for t in range(4)])
    replies = np.array([sum(m.content['i2c'] is not None for i in infos for m in i[t]['messages']) for t in range(4)])
    assert requests.sum() > 0 and replies.sum() > 0
    assert np.allclose(f['requests_received'] * decisions, requests)
    assert np.allclose(f['replies_received'] * decisions, replies)
    assert np.isclose(f['requests_sent'].sum(), f['requests_received'].sum())      # nothing lost without wrappers
    assert (f['broadcasts_sent'] == 0).all()
    # the frames differ from the plain ones exactly at the steps that delivered messages, requests in orange
    assert any(talked for *_, talked in frames) and not all(talked for *_, talked in frames)
    for with_arrows, without, talked in frames:
        assert (not np.array_equal(with_arrows, without)) == talked
    changed = [a[(a != b).any(-1)].astype(int) for a, b, talked in frames if talked]
    orange = [((p[:, 0] >= 180) & (p[:, 1] >= 60) & (p[:, 1] <= 170) & (p[:, 2] <= 90)).sum() for p in changed]
    assert max(orange) > 0                                   # some request arrow shows in orange


def test_tarmac_broadcasts_are_counted(tmp_path):
    from mate.learn.tarmac import TarMACConfig, train

    train(TarMACConfig(team='target', config='MATE-2v4-0', num_envs=2, rollout_length=2, steps=4, epochs=1,
                       hidden=(16,), lstm=16, seed=0, threads=1, run_dir=str(tmp_path), progress=False))
    policy = load_policy(tmp_path / 'final.pt', 'target')
    features, infos, _, steps = _record('MATE-2v4-0', lambda seed: PolicyTargetAgent(policy, seed=seed), 12)
    f = dict(zip(NAMES, features.T))
    decisions = steps / policy.spec.frame_skip
    own = np.array([sum(m.sender == t for i in infos for m in i[t]['messages']) for t in range(4)])
    others = np.array([sum(m.sender != t for i in infos for m in i[t]['messages']) for t in range(4)])
    assert own.sum() > 0 and np.allclose(f['broadcasts_sent'] * decisions, own)     # each broadcast reaches its sender
    assert np.allclose(f['broadcasts_received'] * decisions, others) and np.array_equal(others, own.sum() - own)
    assert (f['requests_sent'] == 0).all() and (f['replies_received'] == 0).all()


def _synthetic(two_roles: bool, episodes=20, targets=8, seed=0):
    rng = np.random.default_rng(seed)
    x = np.zeros((episodes, targets, len(NAMES)))
    first = np.arange(targets) < targets // 2 if two_roles else np.zeros(targets, dtype=bool)
    idx = {n: i for i, n in enumerate(NAMES)}
    x[..., idx['tracked']] = np.where(first, 0.8, 0.2) + 0.05 * rng.standard_normal((episodes, targets))
    x[..., idx['deliveries']] = np.where(first, 1.0, 6.0) + 0.7 * rng.standard_normal((episodes, targets))
    x[..., idx['camera_distance']] = np.where(first, 200.0, 600.0) + 60 * rng.standard_normal((episodes, targets))
    x[..., idx['loaded']] = 0.5 + 0.1 * rng.standard_normal((episodes, targets))
    return x


def test_two_roles_are_found_and_one_role_is_not():
    analysis = roles_script.roles(_synthetic(True))
    assert analysis['distinct'] and analysis['k'] == 2 and analysis['silhouette'] >= 0.5
    groups = {tuple(c['targets']): c for c in analysis['clusters']}
    assert set(groups) == {(0, 1, 2, 3), (4, 5, 6, 7)}
    assert groups[(0, 1, 2, 3)]['label'] == 'distractor-like'
    description = groups[(0, 1, 2, 3)]['description']
    assert 'tracked often' in description and 'near cameras' in description and 'few deliveries' in description
    assert groups[(4, 5, 6, 7)]['label'] == 'running-back-like'
    one = roles_script.roles(_synthetic(False))
    assert not one['distinct'] and one['min_pair_separation'] < 2.0
    assert all(c['label'] == '' and c['description'] == '' for c in one['clusters'])
    assert one['verdict'].startswith('no distinct roles')
    same = roles_script.roles(np.ones((3, 8, len(NAMES))))
    assert not same['distinct'] and same['clusters'] == []


def test_the_script_writes_json_and_a_gif_and_reports_errors_in_the_cli_format(tmp_path, capsys):
    out, gif = tmp_path / 'roles.json', tmp_path / 'roles.gif'
    assert roles_script.main(['--episodes', '2', '--max-episode-steps', '20', '--json', str(out), '--gif', str(gif),
                              '--frame-size', '100', '--frame-every', '5']) == 0
    text = capsys.readouterr().out
    assert '| target | tracked |' in text and 'Roles: ' in text
    import json
    data = json.loads(out.read_text())
    assert np.array(data['per_episode']).shape == (2, 8, len(NAMES)) and 'verdict' in data['roles']
    assert gif.stat().st_size > 0
    for argv, message in ((['--target-agent', 'nobody'], "unknown target agent 'nobody'"),
                          (['--episodes', '0'], '--episodes must be at least 1'),
                          (['--episodes', 'x'], "invalid int value: 'x'"),
                          (['--gif', str(tmp_path / 'x.png')], 'must end with .gif'),
                          (['--target-agent', f'checkpoint:{tmp_path / "missing.pt"}'], 'missing.pt')):
        assert _exit_status(argv) == 2
        err = capsys.readouterr().err
        first, *rest = err.strip().splitlines()
        assert message in first and rest in ([], ['(see target_roles.py -h)']), err


def _exit_status(argv) -> int:
    """The script's exit status: main's return value, or the status of the SystemExit of an argument error."""
    try:
        return roles_script.main(argv)
    except SystemExit as exc:
        return exc.code


def test_mate_evaluate_render_communication(tmp_path):
    from mate.cli.main import main
    gif = tmp_path / 'talk.gif'
    assert main(['evaluate', '--config', 'MATE-2v4-0', '--episodes', '1', '--max-episode-steps', '6',
                 '--render-communication', '1', '--message-kinds', '--save-gif', str(gif), '--frame-size', '100',
                 '--frame-every', '1']) == 0
    assert gif.stat().st_size > 0
