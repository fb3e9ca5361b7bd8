"""The package writes its TOML with the CLI's writer (lgvi._core.toml_text, src/io/toml_writer.hpp):
floats as Python's repr spells them, every table of a document, and what it writes reads back to
the same document (tomllib, an independent reader, is the reference)."""
import math
import os
import pathlib
import random
import re
import struct
import tomllib

import numpy as np
import pytest

SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytest.importorskip("lgvi._core", reason="the built lgvi package (build/python) is not on PYTHONPATH")
import lgvi  # noqa: E402
from lgvi import _core  # noqa: E402


def test_floats_are_spelled_as_repr_and_read_back_to_the_same_double():
    rng = random.Random(1)
    values = [0.1, 0.1 + 0.2, -0.0, 1e-4, 1e-5, 1e15, 1e16, 5e-324, 1.7976931348623157e308]
    while len(values) < 20000:  # any bit pattern that is a finite double
        x = struct.unpack("<d", struct.pack("<Q", rng.getrandbits(64)))[0]
        if math.isfinite(x):
            values.append(x)
    values += [rng.uniform(-1.0, 1.0) * 10.0 ** rng.randint(-30, 30) for _ in range(20000)]
    text = _core.toml_text({"t": {"x": values}})
    body = text[text.index("[", text.index("x =")) + 1:text.rindex("]")]
    assert [token.strip() for token in body.split(",")] == [repr(v) for v in values]
    back = tomllib.loads(text)["t"]["x"]
    assert struct.pack(f"<{len(values)}d", *back) == struct.pack(f"<{len(values)}d", *values)  # bit for bit


def test_a_document_reads_back_equal():
    doc = {"body": {"mass": 2.0, "name": 'a "quoted" \\ name\twith é', "ball": [{"position": [0.0, 1e-3, 0.0]},
                                                                             {"position": [1.0, 0.0, 0.0]}]},
           "initial": {"orbit": {"altitude": 500e3, "inclination": 51.6}, "n": [1, -2, 2**62], "flag": True},
           "empty": {}}
    assert tomllib.loads(_core.toml_text(doc)) == doc


@pytest.mark.parametrize("value, kind", [(np.zeros(3), TypeError), (2**64, ValueError), (None, TypeError)])
def test_a_value_toml_cannot_hold_is_refused(value, kind):
    with pytest.raises(kind, match="cannot write"):
        _core.toml_text({"t": {"x": value}})


def single_body_scenarios():
    for path in sorted((SOURCE / "scenarios").glob("*.toml")):
        doc = tomllib.loads(path.read_text())
        if "bodies" not in doc and "import" not in doc:
            yield path


@pytest.mark.parametrize("path", list(single_body_scenarios()), ids=lambda p: p.stem)
def test_replace_keeps_every_table_of_the_scenario(path):
    # Scenario.replace wrote [body], [potential], [initial], [integrator] and [output] only: a scenario's
    # [[forcing]], [[sensor]], [run] (and anything else) vanished without a word.
    sc = lgvi.Scenario.from_toml(path)
    changed = sc.replace(duration=sc.duration / 2)
    expected = sc.document
    expected["integrator"]["duration"] = sc.duration / 2
    assert changed.document == expected
    # ... and runs as the file does with the same change made in its text: the same rows, bit for bit.
    if "step" in sc.document["integrator"]:
        duration = 20 * sc.step
        text, n = re.subn(r"^duration = .*$", f"duration = {duration!r}", path.read_text(), flags=re.M)
        assert n == 1
        edited = lgvi.Scenario.from_string(text, name=sc.name)
        assert np.array_equal(lgvi.simulate(sc.replace(duration=duration)).data, lgvi.simulate(edited).data)


def test_replace_keeps_the_attitude_controller():
    sc = lgvi.Scenario.from_toml(SOURCE / "scenarios" / "attitude-slew.toml")
    assert "forcing" in sc.document
    half = sc.replace(step=sc.step / 2)
    assert half.document["forcing"] == sc.document["forcing"]
    # Under control the body slews; the controller dropped, it would spin freely: the end attitudes differ.
    free = lgvi.Scenario.from_string(half.toml.split("[[forcing]]")[0], name="free")
    assert not np.allclose(lgvi.simulate(half).q[-1], lgvi.simulate(free).q[-1], atol=1e-3)


def test_names_beyond_ascii_are_escaped_for_the_reader():
    # The scenario reader takes ASCII only outside comments; the writer escapes the rest (\uXXXX).
    sc = lgvi.Scenario.from_arrays(bodies=lgvi.Body(mass=1.0, inertia=np.eye(3)),
                                   positions=[[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]],
                                   quaternions=[[1.0, 0.0, 0.0, 0.0]] * 2, velocities=np.zeros((2, 3)),
                                   omegas=np.zeros((2, 3)), names=["é", "Ω-b"], step=0.1, duration=0.2)
    assert sc.toml.isascii()
    assert [b["name"] for b in tomllib.loads(sc.toml)["bodies"]] == ["é", "Ω-b"]
    summary = lgvi.simulate(sc).summary
    assert [b["name"] for b in summary["setup"]["bodies"]] == ["é", "Ω-b"]


def test_a_list_that_holds_itself_is_a_recursion_error():
    a = []
    a.append(a)
    with pytest.raises(RecursionError):
        _core.toml_text({"t": {"x": a}})
