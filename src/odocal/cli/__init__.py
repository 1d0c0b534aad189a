"""The ``odocal`` command line: argparse and printing only; each command calls its function in
:mod:`odocal.app` (``main`` dispatches)."""
