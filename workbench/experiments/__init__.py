"""One package per paper. ``EXPERIMENTS`` names those that exist, for ``workbench list``."""

EXPERIMENTS: dict[str, str] = {
    "sea": "paper 002: object on the sea from a monocular camera; geometric, diffuse RLS, "
    "sliding-window RLS, EKF against a GTSAM smoother (LM and iSAM2)",
}
