"""``odocal fit BAG --method auto`` on real bags (the typed seam's verdicts, issue 27): what a
held parameter, a robot file in the wrong units, or a ground truth taken for the wheels did to
real answers."""

from __future__ import annotations

import pytest

from odocal.app.fit_auto import fit_auto


@pytest.fixture(scope="module")
def mit_halves(realdata):
    robot = realdata / "mit_csail" / "robot_virtual.yaml"
    return [
        fit_auto(realdata / "mit_csail" / f"csail_half{k}", robot=robot) for k in (1, 2)
    ]


def test_a_held_parameter_is_never_cross_checked_and_the_mit_halves_agree(mit_halves):
    # before: each half's one restricted route held b at nominal with a "std. error 0", and
    # that alone made both halves "NOT to be trusted" (slam vs scan on b: -3.08, +4.62)
    for res in mit_halves:
        held = {
            p.name
            for r in res.routes
            if r.answer is not None
            for p in r.answer.parameters
            if p.status == "held"
        }
        assert held, "a route settles on a restricted model on each half"
        assert not [c for c in res.cross_checks if c.quantity in held]
        assert res.enough, res.reasons
        d = res.as_dict()
        for r in d["routes"]:
            for name, p in r.get("parameters", {}).items():
                if p["status"] == "held":
                    assert p["std_error"] is None, (r["name"], name)
        assert "held" in res.text()
    # the halves' answers agree with each other where both measured (independent data)
    a, b = (res.answer.answer for res in mit_halves)
    ma, mb = a.mean_diameter(), b.mean_diameter()
    assert abs(ma[0] - mb[0]) < 3 * (ma[1] ** 2 + mb[1] ** 2) ** 0.5
