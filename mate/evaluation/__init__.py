"""Evaluation: the benchmark's protocol for any policy (`protocol`: held-out seeds, the absolute metric, references on
the same seeds; `mate.score_policy`), episodes of camera agents against target agents (`evaluate`) and the
`mate evaluate` command (`command`)."""
