"""The halftone terrain model: ground coordinates per pixel, measuring in it, its files (GeoTIFF,
mesh) and the measure command."""
