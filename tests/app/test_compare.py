"""``odocal.app.compare.compare`` tested on its typed result: what ``odocal compare`` prints is
read from these fields (the CLI computes nothing); the real-data comparison's golden values."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.app.compare import compare, comparison_document
from odocal.comparison.methods import METHOD_REGISTRY
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


def test_the_real_comparison_calibrates_and_validates_on_held_out_runs(realdata):
    res = compare(trials=2, realdata=realdata / "optiodom_diff")
    real = res.real
    assert real is not None and len(real.heldout) == 13
    assert [m.name for m in real.methods] == [e.name for e in METHOD_REGISTRY]
    # Held-out validation (tests/io/test_optiodom.py: the split). Golden values measured with
    # this code (deterministic); the published OptiOdom parameters were fitted on all data,
    # held-out runs included, so they are a lower reference.
    assert real.nominal_mean_final_error_m == pytest.approx(0.0546, abs=5e-4)
    doc = comparison_document(res)["realdata"]
    published = doc["published"]["heldout_mean_final_error_m"]
    assert published == pytest.approx(0.0124, abs=5e-4)
    summary = {m["name"]: m["heldout_mean_final_error_m"]["mean"] for m in doc["methods"]}
    assert summary["heading"] == pytest.approx(0.0185, abs=5e-4)
    assert summary["bcpt"] == pytest.approx(0.0166, abs=5e-4)
    assert summary["ivanjko"] == pytest.approx(0.0326, abs=5e-4)
    assert summary["trajectory"] == pytest.approx(0.0183, abs=5e-4)
    # Every method but linear improves on nominal parameters; none beats the published all-data
    # fit. Linear least squares uses each run's net displacement and rotation, which closed
    # squares, straight lines and spins condition badly: it ends worse than nominal here.
    linear = summary.pop("linear")
    assert linear > real.nominal_mean_final_error_m
    for v in summary.values():
        assert published < v < real.nominal_mean_final_error_m
    agree: dict = {}
    for a in res.published_same_method:
        agree.setdefault(a.method, []).append(a.max_abs_difference_m)
    # Our UMBmark x-form and Ivanjko reproduce the published columns (6 printed digits; Ivanjko
    # within 1e-5 m, see test_ivanjko); our exact heading method is NOT the published
    # Jung&Chung code (chord and coupling terms), so it differs by up to a few mm in b.
    assert len(agree["umbmark-x"]) == 8 and max(agree["umbmark-x"]) < 1.5e-6
    assert len(agree["ivanjko"]) == 8 and max(agree["ivanjko"]) < 1e-5
    assert max(agree["heading"]) > 1e-4
