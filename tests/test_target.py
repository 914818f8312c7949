"""Rattle targets (rattle_core.model.target): limit curves, pass/fail ranges, refusals."""
from __future__ import annotations

import numpy as np
import pytest

from rattle_core.model.target import Target, fail_ranges, format_ranges


def test_the_limit_is_interpolated_and_held_beyond_its_corners():
    """Linear between corners, constant beyond the first and last."""
    t = Target.from_table({"rpm": [1000, 3000], "sone": [10, 30]})
    assert t.limit("sone", [500, 1000, 2000, 3000, 4000]) == pytest.approx([10, 10, 20, 30, 30])


def test_the_cli_form_reads_both_curves():
    """'RPM:VALUE,... sone; RPM:VALUE,... dba' gives both limits on the same corners."""
    t = Target.parse("1000:10,3000:20 sone; 1000:60,3000:70 dba")
    assert t.rpm == (1000.0, 3000.0)
    assert t.limits == {"sone": (10.0, 20.0), "dba": (60.0, 70.0)}


def test_failing_ranges_are_every_run_of_failures():
    """A gear that fails, passes, then fails again has two failing ranges."""
    rpm = np.arange(1000, 2100, 100.0)
    passed = np.array([1, 0, 0, 1, 1, 0, 0, 0, 1, 1, 0], bool)
    ranges = fail_ranges(rpm, passed)
    assert ranges == [(1100, 1200), (1500, 1700), (2000, 2000)]
    assert format_ranges(ranges) == "1100-1200; 1500-1700; 2000-2000"
    assert fail_ranges(rpm, np.ones(rpm.size, bool)) == []


@pytest.mark.parametrize("table, words", [
    ({"rpm": [1000, 900], "sone": [1, 2]}, "increase strictly"),
    ({"rpm": [1000, 2000], "sone": [1]}, "one value per rpm"),
    ({"rpm": [1000], "dba": [250]}, r"dba\[0\].*\[0, 200\]"),
    ({"rpm": [1000]}, "sone and/or dba"),
    ({"rpm": [1000], "phon": [3]}, "unknown key"),
    ({"sone": [3]}, "rpm is required"),
])
def test_bad_targets_are_refused_with_the_key_and_range(table, words):
    """A target that cannot be a limit curve is refused naming the key and what is allowed."""
    with pytest.raises(ValueError, match=words):
        Target.from_table(table)


@pytest.mark.parametrize("text", ["1000:10 phon", "1000-10 sone", "abc sone", "1000:10,2000:12"])
def test_bad_cli_targets_are_refused(text):
    """The CLI form says what it expects."""
    with pytest.raises(ValueError, match="target"):
        Target.parse(text)
