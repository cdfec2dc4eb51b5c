"""droneid fit reads plain numeric CSV tables without pandas, to the same float64 values pandas
gives, and hands everything else to pandas (issue 26: pandas' import is a fifth of the start-up)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from droneid.engine.fit import FitConfig, prepare, read_plain_table


def _same_as_pandas(path) -> None:
    plain = read_plain_table(path)
    assert plain is not None, path.read_text()[:200]
    df = pd.read_csv(path)
    assert list(plain) == [str(c) for c in df.columns]
    for name, values in plain.items():
        if values is None:
            assert name == "flight" and not pd.api.types.is_numeric_dtype(df[name])
            continue
        expected = df[name].to_numpy(dtype=np.float64)
        # bit for bit, the sign of zero included
        assert values.dtype == np.float64 and values.tobytes() == expected.tobytes(), name


@pytest.mark.parametrize("fmt", ["%.17g", "%.18e", "%.6f", "%.3g", "%.0f", "%d"])
def test_random_tables_read_bit_for_bit_as_pandas_reads_them(tmp_path, fmt):
    rng = np.random.default_rng(len(fmt))
    x = rng.normal(size=(3000, 4)) * 10.0 ** rng.integers(-12, 12, size=(3000, 4))
    if fmt == "%d":
        x = np.round(x).clip(-1e17, 1e17).astype(np.int64)
    path = tmp_path / "t.csv"
    np.savetxt(path, x, delimiter=",", header="a,b,c,d", comments="", fmt=fmt)
    _same_as_pandas(path)


@pytest.mark.parametrize("text", [
    "a,b\n-0,1\n00,+2\n-5,3\n",                   # an int64 column in pandas: -0 is 0.0
    "a,b\n-0,1.5\n0.0,-0\n1e3,.5\n",               # a float column: -0 stays -0.0
    "a,b\r\n1,2\r\n3,4\r\n",                       # CRLF
    "t,flight,x\n0,run1,1\n0.05,run1,2\n",        # log names in the flight column
    "a,b\n1e400,1\n1e-400,2\n4.9406564584124654e-324,3\n123456789012345678901234567890.5,4\n",
    "a,b\n1,2\n3,4",                               # no final newline
])
def test_edge_cases_match_pandas(tmp_path, text):
    path = tmp_path / "t.csv"
    path.write_bytes(text.encode())
    _same_as_pandas(path)


@pytest.mark.parametrize("text", [
    "a,b\n1,nan\n2,3\n", "a,b\n1,\n2,3\n", "a,b\n1, 2\n3,4\n", "a,b\n1,2\n\n3,4\n",
    "a,a\n1,2\n", "a,\n1,2\n", "a,b\n1,2,3\n", 'a,b\n"1",2\n', "\ufeffa,b\n1,2\n",
    "a,b\n12345678901234567890,1\n", "a,b\n1,inf\n", "a,b\n1,x\n", "a\n1\n", "a,b\n",
])
def test_anything_else_is_left_to_pandas(tmp_path, text):
    path = tmp_path / "t.csv"
    path.write_bytes(text.encode())
    assert read_plain_table(path) is None


def test_a_non_numeric_input_still_gets_pandas_and_its_error(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("flight,x,y\nrun1,1,2\nrun1,2,3\nrun1,3,4\nrun1,4,5\n")
    from droneid.errors import DataError
    with pytest.raises(DataError, match="column 'flight' is not numeric"):
        prepare(path, FitConfig(target="y", inputs=("flight", "x")))


def test_fit_reads_a_plain_table_without_importing_pandas(tmp_path):
    path = tmp_path / "t.csv"
    rng = np.random.default_rng(0)
    np.savetxt(path, rng.normal(size=(40, 3)), delimiter=",", header="a,b,y", comments="")
    code = ("import sys; from droneid.engine.fit import FitConfig, prepare; "
            f"p = prepare({str(path)!r}, FitConfig(target='y')); "
            "print(p.X.shape, 'pandas' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.split() == ["(40,", "2)", "False"], r.stdout + r.stderr
