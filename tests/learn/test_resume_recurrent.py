"""Exact resumes of the recurrent PPO trainers (`mappo_lstm`, `tarmac`, `i2c`): a run stopped by SIGINT and resumed
ends with the same weights, optimiser state and log rows as the run never stopped. Besides the networks, optimiser,
generators and envs, what they carry over is the actors' memory between iterations and the `starting` flags (the
episodes cut by the horizon inside the rollouts make both matter), and for a lossy channel its own generator."""

from __future__ import annotations

import os
import shutil
import signal

import pytest
import torch

from mate.learn import i2c, mappo_lstm, tarmac
from mate.policies.checkpoint import load_checkpoint, save_checkpoint

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


@pytest.mark.parametrize('name', TRAINERS)
def test_a_checkpoint_without_the_envs_restarts_every_episode_from_zero_memory(tmp_path, name):
    """An older checkpoint without the batch's state resets the envs (`Run.first_observations`): the memory it
    saved belongs to episodes that no longer exist, so every episode starts from zero memory and what that memory
    held cannot change the run."""
    train, config_class, options = TRAINERS[name]

    def config_of(run_dir, fresh):
        return config_class(**TINY, **options, run_dir=str(run_dir), fresh=fresh)

    def stop(row):                                                      # a checkpoint after iteration 1
        if row['iteration'] == 1:
            os.kill(os.getpid(), signal.SIGINT)

    assert train(config_of(tmp_path / 'first', True), callback=stop).interrupted
    finals = []
    for junk in (None, 5.0):
        run_dir = tmp_path / f'older-{junk}'
        shutil.copytree(tmp_path / 'first', run_dir)
        data = load_checkpoint(run_dir / 'checkpoint.pt')
        del data['state']['envs']                                       # as written before envs were saved
        if junk is not None:
            data['state']['memory'] = [torch.full_like(part, junk) for part in data['state']['memory']]
        save_checkpoint(run_dir / 'checkpoint.pt', data)
        train(config_of(run_dir, False))
        finals.append(run_dir)
    assert_same_run(*finals)
