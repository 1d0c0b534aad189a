"""app.design_route: the skid-steer design is the differential design of the effective track;
targets parse with their units."""

from __future__ import annotations

import pytest

from odocal.app.design_route import design_for_route, parse_target
from odocal.errors import InputError

SKID = """\
wheel_diameter_m: 0.33
wheelbase_m: 0.55
nonsystematic: {k_r_m: 4.0e-6, k_l_m: 4.0e-6}
kinematics: skid_steer
wheel_separation_multiplier: 1.8
"""
DIFF = """\
wheel_diameter_m: 0.33
wheelbase_m: 0.99
nonsystematic: {k_r_m: 4.0e-6, k_l_m: 4.0e-6}
"""


# a handful of Monte Carlo trials says little of the spread: its comparison warnings are noise
@pytest.mark.filterwarnings("ignore::odocal.errors.OdocalWarning")
def test_skid_steer_designs_for_the_effective_track(tmp_path):
    (tmp_path / "skid.yaml").write_text(SKID)
    (tmp_path / "diff.yaml").write_text(DIFF)
    kw = {"duration_s": 120.0, "trials": 5, "seed": 4}
    skid = design_for_route("trajectory", tmp_path / "skid.yaml", **kw)
    diff = design_for_route("trajectory", tmp_path / "diff.yaml", **kw)
    assert skid.kinematics == "skid-steer"
    assert any("effective track 0.99 m" in n for n in skid.notes)
    # 0.55 m x 1.8 = 0.99 m: the same predictions as a differential drive of that wheelbase
    for a, b in zip(skid.design.candidates, diff.design.candidates, strict=True):
        assert a.mix == b.mix
        for k, v in a.predicted_std_error.items():
            assert v == pytest.approx(b.predicted_std_error[k], rel=1e-6)
    assert "effective track" in skid.text()


@pytest.mark.parametrize(
    ("text", "relative", "value"),
    [("wheelbase=0.2%", True, 0.002), ("wheel_diameter=0.05mm", False, 5e-5),
     ("wheelbase=0.001m", False, 0.001), ("diameter_ratio=0.0005", False, 0.0005)],
)  # fmt: skip
def test_targets_parse_with_units(text, relative, value):
    t = parse_target(text)
    assert t.relative is relative and t.value == pytest.approx(value, rel=1e-12)


@pytest.mark.parametrize("text", ["wheelbase", "wheelbase=-1%", "wheelbase=nan%", "x=1%",
                                  "diameter_ratio=1mm", "wheelbase=1"])  # fmt: skip
def test_bad_targets_are_refused(text):
    with pytest.raises(InputError):
        parse_target(text)
