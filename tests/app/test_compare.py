"""``odocal.app.compare.compare`` tested on its typed result: what ``odocal compare`` prints is
read from these fields (the CLI computes nothing)."""

from __future__ import annotations

import numpy as np

from odocal.app.compare import compare, comparison_document
from odocal.comparison.real import PublishedAgreement, summarize_agreement
from odocal.core.model import WheelGeometry


def test_the_simulated_comparison_is_typed():
    res = compare(trials=4, runs=10, seed=2)
    sim = res.simulated
    assert res.real is None and res.agreement == () and res.published_same_method == ()
    doc = comparison_document(res, robot="paper-fig5")
    methods = {m["name"]: m for m in doc["simulated"]["methods"]}
    for m in sim.methods:
        fe = m.final_error
        finite = m.final_error_m[np.isfinite(m.final_error_m)]
        if finite.size:
            assert fe.mean == float(finite.mean())
        assert methods[m.name]["final_error_m"] == fe.as_dict()
        assert methods[m.name]["E_b_error"] == {"bias": m.E_b_stats.bias, "std": m.E_b_stats.std}
    nominal = sim.nominal_final_error
    assert nominal.mean == float(sim.nominal_final_error_m.mean())
    assert doc["simulated"]["nominal"]["final_error_m"] == nominal.as_dict()


def test_the_agreement_with_the_published_methods_is_summarised():
    g = WheelGeometry(0.084, 0.084, 0.2)

    def row(method: str, dataset: str, db: float) -> PublishedAgreement:
        return PublishedAgreement(method, "UMBmark", dataset, g, db, 0.0, -0.5 * db)

    rows = (row("umbmark-x", "a", 1e-6), row("umbmark-x", "b", -3e-6), row("umbmark-x", "c", 2e-6))
    assert [r.max_abs_difference_m for r in rows] == [1e-6, 3e-6, 2e-6]
    (s,) = summarize_agreement(rows)
    assert (s.method, s.published_method, s.datasets) == ("umbmark-x", "UMBmark", 3)
    assert s.largest_m == 3e-6 and s.median_m == 2e-6
    d = rows[0].as_dict()
    assert d["difference"] == {
        "wheelbase_m": 1e-6,
        "wheel_diameter_right_m": 0.0,
        "wheel_diameter_left_m": -5e-7,
    }
    assert d["published"] == g.as_dict()
