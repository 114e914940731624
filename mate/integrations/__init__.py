"""Adapters of `mate` to other multi-agent APIs: `pettingzoo` (Parallel and AEC) and `rllib`
(Ray RLlib's MultiAgentEnv). Each module imports its library lazily enough that `import mate`
never needs it; install the extras `mate[pettingzoo]` or `mate[rllib]`."""
