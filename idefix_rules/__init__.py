"""idefix-rules: verification of driving command chains for the MMX rover IDEFIX."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("idefix-rules")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+source"
