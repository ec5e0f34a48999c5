"""The omni experiment's files: the MRCLAM dataset, the open log format, the real scenario
assembled from them, TUM export."""
