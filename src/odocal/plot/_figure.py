"""The one way odocal makes a figure: a matplotlib ``Figure`` on the Agg canvas (no pyplot, no
global backend change), with one install hint when matplotlib is missing. Writing the figure is the
caller's business (``odocal.io.outputs``)."""

from __future__ import annotations

from typing import Any

from ..errors import OdocalError

__all__ = ["new_figure", "require_matplotlib", "INSTALL_HINT"]

INSTALL_HINT = "plotting needs matplotlib: pip install 'odocal[plot]'"


def new_figure(width: float = 7.0, height: float = 4.4, dpi: float = 120) -> Any:
    """A new ``matplotlib.figure.Figure`` (inches, constrained layout) on an Agg canvas."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise OdocalError(INSTALL_HINT) from None
    fig = Figure(figsize=(width, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def require_matplotlib() -> None:
    """Raise the one-line install hint unless matplotlib can be imported (check before work)."""
    new_figure()
