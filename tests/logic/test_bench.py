"""The LTL benchmark (`mrodrake bench ltl`) meets the issue's targets (slow: it also times Spot)."""

import io

import pytest

from mrodrake.bench.ltl import run_ltl_benchmark


@pytest.mark.slow
def test_ltl_benchmark_meets_targets():
    out = io.StringIO()
    result = run_ltl_benchmark(stream=out)
    text = out.getvalue()
    assert "Dwyer total states" in text and "case II" in text
    assert result["dwyer"]["count"] == 55
    assert all(result["targets"].values()), result["targets"]
    for case in result["case_studies"]:
        assert case["states"] <= case["paper_states"]
