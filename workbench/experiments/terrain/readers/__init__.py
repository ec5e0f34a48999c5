"""The terrain experiment's files: the NGI frames and orientation, the open log format."""
