"""Tools beside the game: the throughput benchmark (`bench`), the config generator (`generator`), video files
(`video`), figures (`plotting`), where independent jobs run (`runners`) and the pinned PyTorch kernels of
`MATE_REPRODUCIBLE=1` (`reproducible`). Importing this package imports nothing."""
