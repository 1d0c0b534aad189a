"""Figures (matplotlib, imported lazily): each function takes results and returns figures; the app
layer writes them (``odocal.io.outputs``)."""
