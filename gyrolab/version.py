"""The installed distribution's version, for the package, the results' provenance and the workers."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("gyrolab")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0+unknown"
