"""A CSV whose first data row has empty fields (NaN as pandas writes it) keeps its header."""

import numpy as np
import pytest

from senscal.errors import DataError
from senscal.io import read_recording


def test_empty_fields_in_first_data_row_are_data_not_header(tmp_path):
    p = tmp_path / "w.csv"
    p.write_text("t,a,b,c\n0,,1,\n1,2,3,4\n2,2,3,4\n")
    rec = read_recording(p, allow_nan=True)
    assert list(rec.names) == ["a", "b", "c"]
    np.testing.assert_array_equal(rec.time, [0.0, 1.0, 2.0])
    assert np.isnan(rec.data(["a"])[0, 0]) and rec.data(["b"])[0, 0] == 1.0


def test_nan_row_still_refused_without_allow_nan(tmp_path):
    p = tmp_path / "w.csv"
    p.write_text("t,a,b\n0,,1\n1,2,3\n")
    with pytest.raises(DataError, match="NaN in data row 1"):
        read_recording(p)
