"""The fuzz of issue 29 with warnings turned into errors: ``droneid inspect`` on damaged copies of
the shared real logs raises no Python warning (before the fix: "Mean of empty slice" on ULogs,
"overflow encountered in square" on MCAPs, "All-NaN slice encountered" on a ULog)."""
from __future__ import annotations

import contextlib
import io
import random
import warnings

import pytest

from droneid.cli import main
from fuzz_check import mutate

from conftest import real_log

pytestmark = pytest.mark.real_logs

LOGS = {"px4/vtol_short_hop.ulg": [], "px4/quad_fmuv5_ground.ulg": [],
        "mcap/sportcub_fixedwing_qualisys.mcap": [],
        "mocap/optitrack_motive/motive_1.23_three_rigid_bodies.csv": ["--body", "device02"]}
N_MUTANTS = 15


@pytest.mark.slow
@pytest.mark.parametrize("rel", sorted(LOGS))
def test_damaged_logs_raise_no_warning(rel, tmp_path):
    src = real_log(rel)
    data = src.read_bytes()
    rng = random.Random(29)
    for k in range(N_MUTANTS):
        kind, damaged = mutate(data, rng)
        p = tmp_path / f"m{k}{src.suffix}"
        p.write_bytes(damaged)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
                try:
                    rc = main(["inspect", str(p), *LOGS[rel]])
                except Warning as w:                  # what the user would have seen
                    pytest.fail(f"mutant {k} ({kind}) of {rel}: {type(w).__name__}: {w}")
        assert rc in (0, 2), (k, kind, err.getvalue()[-500:])
        assert "Warning:" not in err.getvalue(), (k, kind, err.getvalue()[-500:])   # not even as an error line
        assert not any(not c.isprintable() for c in err.getvalue().replace("\n", "")), (k, kind)
