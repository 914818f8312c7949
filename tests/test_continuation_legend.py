"""The cascade's legend sits in the corner of the diagram the branches leave emptiest.

:func:`app.ui.branch_glyphs.legend_corner` counts the branch points in each corner box (a
third of the view each way); the cascade from Λ = 1.2 rises to the right, so the legend must
leave the bottom-right corner where it used to cover the branches.
"""
from __future__ import annotations

import numpy as np

from app.ui.branch_glyphs import legend_corner


def test_the_legend_goes_to_the_corner_without_branch_points():
    """Branches filling the bottom right and the top left push the legend to the top right or
    bottom left, whichever is empty; with no points it stays bottom right."""
    limits = ((0.0, 3.0), (0.0, 3.0))
    lam = np.linspace(2.1, 3.0, 50)
    bottom_right = np.column_stack([lam, np.full_like(lam, 0.5)])
    top_left = np.column_stack([lam - 2.1, np.full_like(lam, 2.5)])
    assert legend_corner([bottom_right, top_left], limits) == "top_right"
    top_right = np.column_stack([lam, np.full_like(lam, 2.5)])
    assert legend_corner([bottom_right, top_left, top_right], limits) == "bottom_left"
    assert legend_corner([], limits) == "bottom_right"
    assert legend_corner([], None) == "bottom_right"


def test_nan_gaps_and_the_data_extent_are_handled():
    """NaN rows (the gaps between polylines) are not points; without limits the data's extent
    is the view."""
    seg = np.array([[0.0, 0.0], [np.nan, np.nan], [1.0, 0.05], [0.95, 0.0]])
    assert legend_corner([seg], None) == "top_left"
    assert legend_corner([np.array([[np.nan, np.nan]])], ((0.0, 1.0), (0.0, 1.0))) == "bottom_right"
