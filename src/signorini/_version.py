"""The version of signorini: the one pyproject.toml gives, as installed."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("signorini")
except PackageNotFoundError:  # the source tree without an install
    __version__ = "0+unknown"
