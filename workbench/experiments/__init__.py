"""One package per paper. ``EXPERIMENTS`` names those that exist, for ``workbench list``."""

EXPERIMENTS: dict[str, str] = {
    "omni": "paper 000: odometer + hemispherical camera; bearing-only EKF-SLAM (UT-gated landmark "
    "initialisation) against GTSAM iSAM2 and batch LM; simulation and the MRCLAM robots",
    "sea": "paper 002: object on the sea from a monocular camera; geometric, diffuse RLS, "
    "sliding-window RLS, EKF against a GTSAM smoother (LM and iSAM2)",
    "terrain": "paper 001: aerial stereo pair + DEM; recurrent-search estimation (a Kalman filter bank "
    "over error hypotheses) against GTSAM bundle adjustment; synthetic and the real NGI frames",
}
