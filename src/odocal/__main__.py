"""``python -m odocal``: the ``odocal`` command."""

from .cli.main import entry

entry()
