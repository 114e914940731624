"""Small trained policies shipped with mate: `NAME.pt` files read by `mate.learn.load_agent('pretrained:NAME', team)`
(`mate evaluate --camera-agent pretrained:NAME`). Each file holds only the actor network, its metadata
(team, preset sizes, frame skip, action form) and the training config; see docs/training.md for how
each was trained and how it scores against the greedy agents."""
