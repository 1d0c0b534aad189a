"""The one way odocal makes a figure: a matplotlib ``Figure`` on the Agg canvas (no pyplot, no
global backend change), with one install hint when matplotlib is missing. Writing the figure is the
caller's business (``odocal.io.outputs``)."""

from __future__ import annotations

import functools
from typing import Any

from ..core.parallel import signals_held
from ..errors import OdocalError

__all__ = [
    "new_figure",
    "require_matplotlib",
    "INSTALL_HINT",
    "METHOD_STYLES",
    "SHAPE_COLOURS",
    "method_style",
    "shape_colour",
]

INSTALL_HINT = (
    "plotting needs matplotlib: pip install matplotlib (or, in the odocal folder, "
    "pip install -e '.[plot]')"
)


def new_figure(width: float = 7.0, height: float = 4.4, dpi: float = 120) -> Any:
    """A new ``matplotlib.figure.Figure`` (inches, constrained layout) on an Agg canvas."""
    canvas_class, figure_class = _matplotlib()
    fig = figure_class(figsize=(width, height), dpi=dpi, layout="constrained")
    canvas_class(fig)
    return fig


def _matplotlib() -> tuple[type, type]:
    """The Agg canvas and the figure class, imported with SIGINT and SIGTERM held back (a
    Ctrl-C or SIGTERM waits until the import is done): an import interrupted inside matplotlib's
    C++ font module leaves a map whose destructor, when the process exits, crashes Python
    ('Fatal Python error: PyThreadState_Get', an abort instead of the command's exit status)."""
    try:
        with signals_held():
            from matplotlib.backends.backend_agg import FigureCanvasAgg

            return FigureCanvasAgg, _figure_class()
    except ImportError:
        raise OdocalError(INSTALL_HINT) from None


@functools.cache
def _figure_class() -> type:
    from matplotlib.figure import Figure

    class LaidOutOnce(Figure):
        """A Figure whose ``savefig`` lays it out once, then draws it once: matplotlib's own
        ``savefig`` of a figure with any layout engine (even the placeholder that
        ``set_layout_engine("none")`` leaves) first walks the whole figure without painting,
        and a constrained layout walks it once more to lay it out; the same pixels either way.
        The layout is then fixed: a figure changed after it was saved keeps it (call
        ``set_layout_engine("constrained")`` to lay it out again)."""

        def savefig(self, *args: Any, **kwargs: Any) -> None:
            engine = self.get_layout_engine()
            if engine is not None:
                import matplotlib

                engine.execute(self)
                # None means no engine at all only where the rc asks for no automatic layout
                with matplotlib.rc_context(
                    {"figure.autolayout": False, "figure.constrained_layout.use": False}
                ):
                    self.set_layout_engine(None)
            super().savefig(*args, **kwargs)

    return LaidOutOnce


def require_matplotlib(load: bool = True) -> None:
    """Raise the one-line install hint unless matplotlib can be imported (check before work).
    ``load`` False: only look for it (no import; the import can then overlap other work)."""
    if load:
        new_figure()
        return
    import importlib.util

    if importlib.util.find_spec("matplotlib") is None:
        raise OdocalError(INSTALL_HINT)


#: One colour and one name per calibration method, in every figure (``odocal compare``, the
#: precision figure of ``reproduce``, ...). Keys are the names the code uses.
METHOD_STYLES: dict[str, tuple[str, str]] = {
    "heading": ("tab:green", "heading method"),
    "umbmark": ("tab:orange", "UMBmark (mean form)"),
    "umbmark-mean": ("tab:orange", "UMBmark (mean form)"),
    "umbmark-x": ("#ffbb78", "UMBmark (x form)"),
    "umbmark-y": ("#8c564b", "UMBmark (y form)"),
    "bcpt": ("tab:red", "BCPT"),
    "ivanjko": ("tab:pink", "Ivanjko"),
    "trajectory": ("tab:cyan", "trajectory fit"),
    "linear": ("tab:olive", "linear least squares"),
    "nominal": ("0.45", "nominal (uncalibrated)"),
}

#: One colour per test-track shape (number of sides), in every figure; none of them is a
#: method's colour.
SHAPE_COLOURS: dict[int, str] = {3: "#393b79", 4: "tab:blue", 6: "#6b6ecf", 8: "tab:purple"}


def method_style(name: str) -> tuple[str, str]:
    """(colour, display name) of a calibration method (unknown names: grey, as given)."""
    return METHOD_STYLES.get(name, ("0.6", name))


def shape_colour(sides: int) -> str:
    """The colour of an N-gon test track."""
    return SHAPE_COLOURS.get(int(sides), "0.3")
