"""Parameter catalogue: Table 1/2 values, SI conversion, validation messages, parsing."""

import math

import numpy as np
import pytest

from railsusp.errors import ParameterError
from railsusp.params import (
    CATALOGUE,
    MAIN_SUSPENSION,
    SYMBOLS,
    ParameterSet,
    bounds,
    check_matrix,
    parse_overrides,
    spec,
)


def test_catalogue_has_the_twenty_study_parameters_in_order():
    assert SYMBOLS == tuple(f"X{i}" for i in range(1, 21))
    assert MAIN_SUSPENSION == tuple(f"X{i}" for i in range(11, 21))
    names = [s.name for s in CATALOGUE]
    assert len(set(names)) == 20


@pytest.mark.parametrize(
    ("symbol", "nominal_display", "lo", "hi"),
    [  # Table 1 nominal, Table 2 range: every main suspension parameter is nominal +-50 %
        ("X11", 1.52, 0.76, 2.28),
        ("X12", 12, 6, 18),
        ("X13", 14, 7, 21),
        ("X14", 10, 5, 15),
        ("X15", 170, 85, 255),
        ("X16", 1.8, 0.9, 2.7),
        ("X17", 1.8, 0.9, 2.7),
        ("X18", 50, 25, 75),
        ("X19", 30000, 15000, 45000),
        ("X20", 1000, 500, 1500),
    ],
)
def test_table_2_ranges(symbol, nominal_display, lo, hi):
    s = spec(symbol)
    assert s.nominal_display == pytest.approx(nominal_display)
    assert s.bounds_display == (lo, hi)
    assert s.bounds[0] < s.nominal < s.bounds[1]


def test_si_conversion_of_documented_unit_choices():
    p = ParameterSet.nominal()
    assert p["X13"] == pytest.approx(14e6)  # MN/m -> N/m
    assert p["X12"] == pytest.approx(0.012)  # mm -> m
    assert p["X18"] == pytest.approx(50e3)  # read as kN·s/m, not MN·s/m
    assert p["X19"] == pytest.approx(30e6)  # read as kN/m: 30 MN/m per cross-brace bar
    assert p["X20"] == pytest.approx(1e9)  # adapter seat, at face value
    assert p["X1"] == 1200.0
    assert p["primary_vertical_stiffness"] == p["X15"]


def test_display_round_trip():
    p = ParameterSet({"X13": 16.1, "X17": 1.91}, units="display")
    assert p.display("X13") == pytest.approx(16.1)
    q = ParameterSet(p.to_display(), units="display")
    assert q == p
    assert ParameterSet(dict(p)) == p


def test_out_of_range_error_names_parameter_value_and_range():
    with pytest.raises(ParameterError) as info:
        ParameterSet({"X13": 30}, units="display")
    msg = str(info.value)
    assert "X13" in msg and "30" in msg and "[7, 21] MN/m" in msg


def test_unknown_name_and_non_finite_values_are_rejected():
    with pytest.raises(ParameterError, match="unknown parameter 'X21'"):
        ParameterSet({"X21": 1.0})
    with pytest.raises(ParameterError, match="X14.*not finite"):
        ParameterSet({"X14": math.nan})
    with pytest.raises(ParameterError, match="X15.*not finite"):
        ParameterSet({"X15": math.inf}, units="display")
    with pytest.raises(ParameterError, match="X1 .*must be positive"):
        ParameterSet({"X1": -5.0})
    with pytest.raises(ParameterError, match="not a number"):
        ParameterSet({"X13": "soft"}, units="display")


def test_range_ends_are_accepted_despite_unit_round_off():
    p = ParameterSet({"X11": 2.28, "X12": 6.0, "X16": 0.9}, units="display")
    assert p["X12"] == pytest.approx(0.006)


def test_parse_overrides_cli_style():
    assert parse_overrides("X13=16.1,X14=8.3") == {"X13": 16.1, "X14": 8.3}
    assert parse_overrides(["x15=164", "secondary_lateral_stiffness=1.91"]) == {
        "X15": 164.0,
        "X17": 1.91,
    }
    with pytest.raises(ParameterError, match="must look like X13=16.1"):
        parse_overrides("X13")
    with pytest.raises(ParameterError, match="'abc' is not a number.*\\[7, 21\\]"):
        parse_overrides("X13=abc")
    with pytest.raises(ParameterError, match="unknown parameter"):
        parse_overrides("Y1=2")


@pytest.mark.parametrize("raw", ["1_6", "\uff10", "\u22125", "\u0661\u0666", "nan", "inf", "1e"])
def test_parse_overrides_takes_plain_ascii_decimals_only(raw):
    """Python's float() read ``X13=1_6`` as 16 and a full-width zero as 0, while a Unicode
    minus was refused: an override is now a plain ASCII decimal number or refused in one
    line naming the override and the accepted form."""
    with pytest.raises(ParameterError) as info:
        parse_overrides(f"X13={raw}")
    text = str(info.value)
    assert f"override 'X13={raw}': '{raw}' is not a number" in text
    assert "accepted a plain decimal number: digits, an optional sign, point and exponent" in text
    assert "[7, 21] MN/m" in text and "\n" not in text


def test_parse_overrides_keeps_every_plain_decimal_form():
    got = parse_overrides("X13=16.1,X14=+8,X15=.5e3,X16= 1.,X17=1.9E0")
    assert got == {"X13": 16.1, "X14": 8.0, "X15": 500.0, "X16": 1.0, "X17": 1.9}


def test_toml_by_symbol_and_by_name(tmp_path):
    f = tmp_path / "wagon.toml"
    f.write_text("[parameters]\nX13 = 16.1\nprimary_lateral_stiffness = 8.3\n")
    p = ParameterSet.from_toml(f)
    assert p["X13"] == pytest.approx(16.1e6)
    assert p["X14"] == pytest.approx(8.3e6)
    assert ParameterSet.from_toml("X15 = 164\n")["X15"] == pytest.approx(164e6)


def test_toml_errors_name_the_file(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text("[parameters]\nX13 = 99\n")
    with pytest.raises(ParameterError, match=r"bad\.toml: X13 .*outside"):
        ParameterSet.from_toml(f)
    f.write_text("X13 = = 1\n")
    with pytest.raises(ParameterError, match="not valid TOML"):
        ParameterSet.from_toml(f)
    with pytest.raises(ParameterError, match="does not exist"):
        ParameterSet.from_toml(tmp_path / "missing.toml")


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (
            "X13 = 16.1\nprimary_longitudinal_stiffness = 7\n",
            "parameter 'primary_longitudinal_stiffness': X13 is given twice (also as 'X13')",
        ),
        ("X13 = 16.1\n[parameters]\nX13 = 8\n", "X13 beside the [parameters] table"),
        ("[parameters]\nX13 = 8\n[parameters2]\nX14 = 8\n", "parameters2 beside the"),
    ],
)
def test_a_parameter_file_that_says_two_things_is_refused(tmp_path, text, needle):
    """parameters.md: a parameter given twice is refused. It held for --set only (stop 56's
    audit): a file naming X13 by symbol and by name took the last, a top-level X13 beside a
    [parameters] table (or a misspelt table) was ignored, silently."""
    f = tmp_path / "p.toml"
    f.write_text(text)
    with pytest.raises(ParameterError) as info:
        ParameterSet.from_toml(f)
    assert str(info.value).startswith(f"{f}: ") and needle in str(info.value)
    with pytest.raises(ParameterError, match="X14 is given twice"):
        ParameterSet({"X14": 8.3e6, "primary_lateral_stiffness": 9e6})
    with pytest.raises(ParameterError, match="X14 is given twice"):
        ParameterSet().replace({"x14": 8.3, "X14": 9.0}, units="display")


def test_replace_validates():
    p = ParameterSet.nominal().replace({"X13": 16.1}, units="display")
    assert p["X13"] == pytest.approx(16.1e6)
    with pytest.raises(ParameterError):
        p.replace({"X13": 1.0}, units="display")


def test_bounds_and_matrix_check():
    lo, hi = bounds(["X13", "X15"])
    np.testing.assert_allclose(lo, [7e6, 85e6])
    np.testing.assert_allclose(hi, [21e6, 255e6])
    good = np.array([[10e6, 100e6], [21e6, 85e6]])
    assert check_matrix(["X13", "X15"], good).shape == (2, 2)
    bad = good.copy()
    bad[1, 1] = 300e6
    with pytest.raises(ParameterError, match="row 1: X15 .*300 MN/m"):
        check_matrix(["X13", "X15"], bad)
    with pytest.raises(ParameterError, match="shape"):
        check_matrix(["X13"], good)
    with pytest.raises(ParameterError, match="fixed"):
        bounds(["X1"])
