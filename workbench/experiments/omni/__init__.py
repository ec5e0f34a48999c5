"""Paper 000: bearing-only SLAM with an odometer and a hemispherical camera."""
