"""The trajectory's column schema is the C++ one (src/io/trajectory_sink.hpp), in Python too.

lgvi._columns keeps its own copy of the column names on purpose: lgvi.load, lgvi.plot and
python3 -m lgvi.plot work from the source tree, which has no compiled module (the CLI draws its
figures that way; tests/CMakeLists.txt's sanitized.cli_pytest runs on it). So the schema is
written in C++ and *checked* here, not imported: this test fails when the two disagree.
"""

import lgvi._core as core
import pytest
from lgvi import _columns, _result, plot


def test_columns_are_the_cpp_headers():
    # Each of the four layouts (single body / bodies, without / with the forcing's work), name by
    # name and in order: a renamed, added or reordered C++ column fails here.
    assert _columns.COLUMNS == tuple(core.TRAJECTORY_HEADER.split(","))
    assert _columns.HEADER == core.TRAJECTORY_HEADER
    assert _columns.BODIES_COLUMNS == tuple(core.BODIES_TRAJECTORY_HEADER.split(","))
    assert _columns.FORCED_COLUMNS == tuple(core.FORCED_TRAJECTORY_HEADER.split(","))
    assert _columns.FORCED_BODIES_COLUMNS == tuple(core.FORCED_BODIES_TRAJECTORY_HEADER.split(","))
    assert _columns.THERMO_COLUMNS == core.THERMO_COLUMNS


def test_the_long_formats_columns_are_named_by_the_file_or_the_summary():
    # 27 columns are the forcing's work or a molecular run's temperature: the summary says which, as the
    # file's header does; without either only the widths without thermodynamic columns are named.
    m = len(_columns.BODIES_COLUMNS)
    assert _columns.bodies_columns(_columns.BODIES_COLUMNS + ("work", "temperature", "pressure")) is not None
    assert _columns.bodies_columns(_columns.BODIES_COLUMNS + ("pressure",)) is None
    assert _columns.bodies_columns(_columns.BODIES_COLUMNS + ("temperature", "work")) is None
    row = [[0.0, 0.0] + [float(i) for i in range(2, m + 1)]]
    forced = _result.Result(row, {"work": 1.0}, layout="long")
    molecular = _result.Result(row, {"thermodynamics": {"temperature": {}}}, layout="long")
    assert forced.columns["work"][0] == m and "temperature" not in forced.columns
    assert molecular.temperature[0] == m and "work" not in molecular.columns
    assert _result.Result(row, layout="long").columns["work"][0] == m  # no summary: 27 are the forced layout
    with pytest.raises(ValueError, match="summary says"):
        _result.Result(row, {"thermodynamics": {"temperature": {}, "pressure": {}}}, layout="long")


def test_figures_need_only_columns_that_exist():
    # plot.REQUIRED_COLUMNS is the figures' selection from the schema, not a second schema: every
    # name in it must be a column of the single-body layout (the figures of a run read it).
    assert set(plot.REQUIRED_COLUMNS) <= set(_columns.COLUMNS)


def test_result_arrays_follow_the_schema():
    # Result addresses columns by position in either layout (views into data); its named
    # accessors must land on the columns of those names.
    n = len(_columns.COLUMNS)
    r = _result.Result([[float(i) for i in range(n)]])
    for name, col in r.columns.items():
        assert col[0] == _columns.COLUMNS.index(name)
    assert r.t[0] == _columns.COLUMNS.index("t") and r.energy[0] == _columns.COLUMNS.index("energy")
    assert tuple(r.L[0]) == tuple(_columns.COLUMNS.index(c) for c in ("Lx", "Ly", "Lz"))
    m = len(_columns.BODIES_COLUMNS)
    s = _result.Result([[0.0, 0.0] + [float(i) for i in range(2, m)]])  # 26 columns: the long layout's
    assert s.energy[0] == _columns.BODIES_COLUMNS.index("energy")
    assert tuple(s.P[0]) == tuple(_columns.BODIES_COLUMNS.index(c) for c in ("Px", "Py", "Pz"))
    assert s.momentum_error[0] == _columns.BODIES_COLUMNS.index("momentum_error")
    assert tuple(s.q[0, 0]) == tuple(_columns.BODIES_COLUMNS.index(c) for c in ("qw", "qx", "qy", "qz"))
    # The per-body columns are (steps, N), the system's (steps,): the split is at "energy".
    assert s.columns["quat_norm_error"].shape == (1, 1) and s.columns["energy"].shape == (1,)
