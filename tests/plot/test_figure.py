"""odocal's figures (odocal.plot._figure): laid out once and drawn once, the pixels matplotlib's
own savefig gives."""

from __future__ import annotations

import io

import numpy as np

from odocal.io.outputs import PNG_METADATA
from odocal.plot._figure import new_figure


def _figure():
    fig = new_figure(4.0, 3.0, dpi=80)
    ax, ax2 = fig.subplots(1, 2)
    x = np.linspace(0.0, 3.0, 50)
    ax.plot(x, np.sin(x), label="a long legend label")
    ax.set_xlabel("side length (m)")
    ax.set_ylabel("final error (mm), a long label")
    ax.legend()
    ax2.bar([1, 2, 3], [3.0, 1.0, 2.0])
    ax2.set_title("a title that needs room")
    fig.suptitle("the layout must make room for all of it")
    return fig


def _png(fig, save) -> bytes:
    buffer = io.BytesIO()
    save(fig, buffer, format="png", metadata=PNG_METADATA)
    return buffer.getvalue()


def test_one_draw_and_the_pixels_of_matplotlibs_own_savefig(monkeypatch):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    reference = _png(_figure(), Figure.savefig)  # matplotlib's: layout, a dry draw, a draw
    draws = []
    real_draw = FigureCanvasAgg.draw

    def counted(self, *args, **kwargs):
        draws.append(self)
        return real_draw(self, *args, **kwargs)

    monkeypatch.setattr(FigureCanvasAgg, "draw", counted)
    fig = _figure()
    ours = _png(fig, type(fig).savefig)
    assert ours == reference
    # painted once (a figure with a layout engine, even the placeholder set_layout_engine("none")
    # leaves, is first walked once more without painting)
    assert len(draws) == 1
    assert fig.get_layout_engine() is None  # the layout is fixed once saved


def test_matplotlib_is_imported_with_the_signals_held(monkeypatch):
    """A Ctrl-C or SIGTERM during matplotlib's import waits until it is done: an import cut
    inside its C++ font module made Python abort at exit (issue #20, 'Fatal Python error:
    PyThreadState_Get' after the one-line message)."""
    import signal

    from odocal.plot import _figure

    real, seen = _figure._figure_class, []

    def recording():
        seen.append(signal.getsignal(signal.SIGTERM))
        return real()

    monkeypatch.setattr(_figure, "_figure_class", recording)
    before = signal.getsignal(signal.SIGTERM)
    _figure.new_figure()
    assert seen and seen[0] is not before  # a holding handler while importing
    assert signal.getsignal(signal.SIGTERM) is before  # and the caller's again after
