"""The package's version: the one place it is written (pyproject.toml reads it from here). A leaf
module, importing nothing, so that the layers that write the version (cli, app) need not import
the package root."""

__version__ = "0.1.0"
