"""Test-track design: which polygon track (shape and size) to drive for calibration, and why.

Pure numpy/scipy (no plotting or argparse). See docs/design.md.

- :mod:`.metrics`: closed-form leg heading errors and the systematic share (Figs. 3, 4).
- :mod:`.spec`: what a design is asked (:class:`DesignSpec`; methods, criteria, engines).
- :mod:`.result`: candidates, error summaries, the validation track.
- :mod:`.sweep`: the Monte-Carlo design procedure (Figs. 5, 6, 9) and its JSON.
- :mod:`.recommend`: the size-selection rule on candidate summaries.
- :mod:`.robust`: the design over plausible errors, for a robot whose errors are unknown.
- :mod:`.reproduce`: the paper's simulations and experiment, regenerated.

The command (``odocal design``: robot files, figures, the work cap) is
:func:`odocal.app.design.design`, also ``odocal.design_track`` from ``import odocal``.
"""

from .metrics import (
    leg_heading_noise_rad,
    leg_heading_systematic_rad,
    systematic_share,
)
from .recommend import Comparison, Recommendation, Stability, recommend
from .result import Candidate, ErrorSummary, ValidationTrack
from .spec import DesignSpec
from .sweep import DesignResult, SimulationSettings, design_json, run_design

__all__ = [
    "Candidate",
    "Comparison",
    "DesignResult",
    "DesignSpec",
    "ErrorSummary",
    "Recommendation",
    "SimulationSettings",
    "Stability",
    "ValidationTrack",
    "design_json",
    "leg_heading_noise_rad",
    "leg_heading_systematic_rad",
    "recommend",
    "run_design",
    "systematic_share",
]
