"""Exact resumes of the recurrent PPO trainers (`mappo_lstm`, `tarmac`, `i2c`): a run stopped by SIGINT and resumed
ends with the same weights, optimiser state and log rows as the run never stopped. Besides the networks, optimiser,
generators and envs, what they carry over is the actors' memory between iterations and the `starting` flags (the
episodes cut by the horizon inside the rollouts make both matter), and for a lossy channel its own generator."""

from __future__ import annotations

import pytest

from mate.learn import i2c, mappo_lstm, tarmac

from .resume import assert_same_run, stopped_and_resumed

# MATE-4v8-9 cameras, 4 envs x 10 decisions per iteration, 3 iterations; episodes of 40 raw steps = 8 decisions
TINY = dict(config='MATE-4v8-9', team='camera', num_envs=4, rollout_length=10, horizon=40, threads=1, progress=False,
            steps=4 * 10 * 3, epochs=2, minibatches=2, hidden=(16,), lstm=8, seed=1)
TRAINERS = {
    'mappo-lstm': (mappo_lstm.train, mappo_lstm.RecurrentConfig, {}),                  # the per-target actor
    'ippo-lstm': (mappo_lstm.train, mappo_lstm.RecurrentConfig, dict(critic='local', actor='mlp')),
    'tarmac': (tarmac.train, tarmac.TarMACConfig, dict(message_dropout=0.3, communication_range=1500.0,
                                                       message_delay=1)),
    'i2c': (i2c.train, i2c.I2CConfig, dict(message_dropout=0.3, communication_range=1500.0, influence_samples=4)),
}


@pytest.mark.parametrize('name', TRAINERS)
def test_a_stopped_run_resumes_exactly(tmp_path, name):
    train, config_class, options = TRAINERS[name]

    def config_of(run_dir, fresh):
        return config_class(**TINY, **options, run_dir=run_dir, fresh=fresh)

    straight, stopped = stopped_and_resumed(train, config_of, 1, tmp_path)
    assert_same_run(straight, stopped)
