"""The set-up of the tests that check deployed communicating agents against their training network."""

import mate
from mate.policies.policy import load_agent, load_policy


def policy_targets_against_greedy(path, wrappers=(), frame_skip=3, seed=3):
    """MATE-2v4-0 (with `wrappers`) reset with `seed`; single policy targets of checkpoint `path` (argmax, holding
    each decision `frame_skip` steps) and greedy cameras, both team-reset. Returns (env, policy, targets,
    cameras, (camera_obs, target_obs), (camera_infos, target_infos))."""
    env = mate.make('MATE-2v4-0-v0', wrappers=wrappers)
    policy = load_policy(path, 'target')
    targets = load_agent(f'checkpoint:{path}', 'target')(seed=0, deterministic=True,
                                                         frame_skip=frame_skip).spawn(env.num_targets)
    cameras = mate.GreedyCameraAgent(seed=0).spawn(env.num_cameras)
    (camera_obs, target_obs), (camera_infos, target_infos) = env.reset(seed=seed)
    mate.group_reset(cameras, camera_obs)
    mate.group_reset(targets, target_obs)
    return env, policy, targets, cameras, (camera_obs, target_obs), (camera_infos, target_infos)
