"""The installed package's version (the package's own metadata), for recordings and sweeps to
store: below everything, so the drawing layer need not import the Python API to read it."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("workbench")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
