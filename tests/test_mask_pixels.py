"""`mask_pixels` gives exactly `np.nonzero`'s rows and columns, in its order."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.perception.mask_pixels import mask_pixels


def _masks():
    rng = np.random.default_rng(7)
    blob = np.zeros((360, 640), dtype=bool)
    blob[100:140, 300:345] = rng.random((40, 45)) > 0.3
    corners = np.zeros((360, 640), dtype=bool)
    corners[0, 0] = corners[-1, -1] = corners[0, -1] = corners[-1, 0] = True
    one = np.zeros((5, 7), dtype=bool)
    one[2, 3] = True
    return {"blob": blob, "corners": corners, "one pixel": one,
            "empty": np.zeros((360, 640), dtype=bool), "full": np.ones((4, 6), dtype=bool),
            "noise": rng.random((60, 80)) > 0.9}


@pytest.mark.parametrize("name", list(_masks()))
def test_the_pixels_are_nonzeros_rows_and_columns_in_its_order(name):
    mask = _masks()[name]
    rows, columns = mask_pixels(mask)
    expected_rows, expected_columns = np.nonzero(mask)
    assert rows.dtype == expected_rows.dtype and columns.dtype == expected_columns.dtype
    np.testing.assert_array_equal(rows, expected_rows)
    np.testing.assert_array_equal(columns, expected_columns)
