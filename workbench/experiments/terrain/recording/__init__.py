"""The terrain recording's parts: the 3D scene, the search, the ground products."""
