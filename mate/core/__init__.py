"""The simulation core: world state as arrays with a leading batch axis and compiled kernels.

Nothing in here imports from the rest of the package. Layers (the Gymnasium env, the
vector env, wrappers, agents) use `mate.core.engine` and the world snapshot functions.
"""
