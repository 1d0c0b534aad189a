"""The figures of ``odocal fit``: what a trajectory fit's result shows, chosen here (the fit
computes, the figure only draws)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..calibration.result import GeometryFit
from ..errors import InputError
from .real_experiment import wheelbase_bands_figure

__all__ = ["FIT_FIGURE", "effective_wheelbase_figure", "fit_figures"]

#: The file name of the effective-wheelbase figure in ``odocal fit --plot DIR``.
FIT_FIGURE = "effective_wheelbase.png"


def _lines(fit: GeometryFit) -> dict[str, float]:
    """The single wheelbases drawn as lines (m): the fit's own; with a motion mix or the banded
    model, the constant fit's and the value for the mix (rescaled to the constant fit's mean
    diameter, the diameters of the band table)."""
    if fit.constant_fit is None:
        return {"one wheelbase (this fit)": float(fit.geometry.wheelbase_m)}
    reference = fit.constant_fit
    return {
        "constant fit": float(reference.wheelbase_m),
        "single value for the motion mix": float(
            fit.geometry.wheelbase_m * reference.mean_diameter_m / fit.geometry.mean_diameter_m
        ),
    }


def _banded_at_reference(fit: GeometryFit) -> dict[str, float] | None:
    """A banded fit's wheelbases rescaled to the constant fit's mean diameter (the same turning
    gains), so that they compare with the band table, which is at that fit's diameters."""
    if fit.banded is None or fit.constant_fit is None or not fit.banded.band_wheelbase_m:
        return None
    scale = float(fit.constant_fit.mean_diameter_m / fit.geometry.mean_diameter_m)
    return {k: v * scale for k, v in fit.banded.band_wheelbase_m.items()}


def effective_wheelbase_figure(fit: GeometryFit) -> Any:
    """The effective wheelbase per band of motion of a trajectory fit (its band table, at the
    constant fit's diameters) with the fit's single wheelbase(s) as lines and a banded model's
    band values as crosses."""
    if fit.effective_wheelbase is None:
        raise InputError("--plot draws the effective wheelbase of a trajectory fit", field="plot")
    return wheelbase_bands_figure(
        {"segment estimate": fit.effective_wheelbase},
        "Effective wheelbase per band of motion",
        _lines(fit),
        _banded_at_reference(fit),
    )


def fit_figures(fit: GeometryFit, folder: str | Path) -> dict[Path, Any]:
    """Path -> figure of every figure of ``fit`` that ``odocal fit --plot folder`` writes."""
    return {Path(folder) / FIT_FIGURE: effective_wheelbase_figure(fit)}
