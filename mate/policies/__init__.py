"""Trained policies, without the trainers: what a policy is (`spec`, `PolicySpec`), its networks (`actors`,
`networks`, `comm`, `hrl`), its memory and velocity columns, its checkpoint files (`checkpoint`), where it computes
(`device`) and a trained policy as a batched team or an agent (`policy`). `mate.learn` trains them; evaluation plays
them (torch is imported by the modules, not by this package)."""
