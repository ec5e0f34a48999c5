"""The omni experiment's image stage: rendered hemispherical frames, detection and association to
landmarks."""
