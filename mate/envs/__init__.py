"""The game's envs: `MultiAgentTracking` (one game), the vector env on the CPU or a CUDA device (`make_vec`), the
single-team vector env (`make_team_vec`), the Gymnasium registration and the pygame renderer. The public names are
re-exported by `mate` (docs/contributors/architecture.md)."""
