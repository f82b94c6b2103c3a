"""The keyword-argument validators: one rule per kind, errors naming the argument, value and range."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgym.cli_errors import is_user_error
from navgym.envs import arguments
from navgym.envs.arguments import ArgumentTypeError


def test_a_wrong_type_is_both_a_type_error_and_a_value_error():
    """Command lines report ValueErrors as the user's input error in one line: wrong types too."""
    with pytest.raises(ArgumentTypeError) as info:
        arguments.real("sigma", "3.0", 0.0, low_open=True)
    assert isinstance(info.value, TypeError) and isinstance(info.value, ValueError)
    assert is_user_error(info.value)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: arguments.real("x", "1", 0.0, 5.0), r"x must be a real number in \[0, 5\]; got '1' \(str\)"),
        (lambda: arguments.real("x", True, 0.0), r"x must be a real number in \[0, inf\); got True"),
        (lambda: arguments.real("x", np.bool_(True)), r"x must be a real number in \(-inf, inf\)"),
        (lambda: arguments.real("x", None), r"x must be a real number"),
        (lambda: arguments.integer("n", 1.5, 1), r"n must be an integer >= 1; got 1.5 \(float\)"),
        (lambda: arguments.integer("n", 3.0, 1, 9), r"n must be an integer in \[1, 9\]; got 3.0"),
        (lambda: arguments.integer("n", True, 0), r"n must be an integer >= 0; got True"),
        (lambda: arguments.flag("f", "no"), r"f must be True or False; got 'no'"),
        (lambda: arguments.flag("f", 1), r"f must be True or False; got 1"),
        (lambda: arguments.interval("p", "ab"), r"p must be a pair \(low, high\) of real numbers"),
        (lambda: arguments.interval("p", 5.0), r"p must be a pair"),
        (lambda: arguments.interval("p", (1.0,)), r"p must be a pair"),
        (lambda: arguments.interval("p", (1.0, 2.0, 3.0)), r"p must be a pair"),
        (lambda: arguments.interval("p", ("1", 2.0)), r"p must be a pair"),
        (lambda: arguments.interval("p", (True, 2.0)), r"p must be a pair"),
        (lambda: arguments.interval("p", ((1, 2), 3)), r"p must be a pair"),
        (lambda: arguments.interval("p", np.ones((1, 2))), r"p must be a pair"),
        (
            lambda: arguments.count_range("c", (1.0, 2), 0, 9),
            r"c must be a pair \(low, high\) of integers in \[0, 9\]",
        ),
        (lambda: arguments.count_range("c", (True, 2)), r"c must be a pair \(low, high\) of integers"),
        (lambda: arguments.count_range("c", "12"), r"c must be a pair \(low, high\) of integers"),
        (lambda: arguments.reals("r", "ab"), r"r must be a tuple of real numbers"),
        (lambda: arguments.reals("r", ("1",)), r"r must be a tuple of real numbers"),
        (lambda: arguments.reals("r", 5.0), r"r must be a tuple of real numbers"),
        (lambda: arguments.instance("o", "bogus", complex), r"o must be a builtins.complex; got 'bogus'"),
    ],
)
def test_wrong_types_raise_naming_argument_value_and_range(call, message):
    with pytest.raises(ArgumentTypeError, match=message):
        call()


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: arguments.real("x", math.nan, 0.0), r"x must be a finite number in \[0, inf\); got nan"),
        (lambda: arguments.real("x", math.inf, 0.0), r"x must be a finite number in \[0, inf\); got inf"),
        (lambda: arguments.real("x", 0.0, 0.0, low_open=True), r"x must be a finite number in \(0, inf\)"),
        (lambda: arguments.real("x", 61.0, 0.0, 60.0), r"x must be a finite number in \[0, 60\]; got 61.0"),
        (lambda: arguments.real("x", 90.0, 0.0, 90.0, high_open=True), r"in \[0, 90\); got 90.0"),
        (lambda: arguments.integer("n", 17, 4, 16), r"n must be an integer in \[4, 16\]; got 17"),
        (
            lambda: arguments.interval("p", (2.0, 1.0)),
            r"p must be .* low <= high; got \(2.0, 1.0\)",
        ),
        (
            lambda: arguments.interval("p", (math.nan, 1.0)),
            r"p must be a pair .* of finite numbers",
        ),
        (lambda: arguments.interval("p", (1.0, 2.0), 0.0, 1.0), r"p must be .* in \[0, 1\] with low"),
        (lambda: arguments.interval("p", (1.0, 90.0), 0.0, 90.0, high_open=True), r"in \[0, 90\) with low"),
        (lambda: arguments.interval("p", (0.0, 1.0), 0.0, low_open=True), r"in \(0, inf\) with low"),
        (lambda: arguments.count_range("c", (1, 10**9), 0, 100), r"c must be .* integers in \[0, 100\]"),
        (lambda: arguments.count_range("c", (3, 2), 0, 100), r"with low <= high; got \(3, 2\)"),
        (lambda: arguments.count_range("c", (-1, 2), 0), r"c must be a pair \(low, high\) of integers >= 0"),
        (lambda: arguments.reals("r", (1.0, math.inf), 0.0), r"r must hold finite numbers in \[0, inf\)"),
        (lambda: arguments.reals("r", (-1.0,), 0.0), r"r must hold finite numbers"),
    ],
)
def test_bad_values_raise_value_errors_naming_argument_value_and_range(call, message):
    with pytest.raises(ValueError, match=message) as info:
        call()
    assert not isinstance(info.value, TypeError)


def test_valid_values_pass_normalized():
    assert arguments.real("x", np.float32(2.5), 0.0) == 2.5
    assert arguments.integer("n", np.int64(3), 1) == 3 and type(arguments.integer("n", np.int64(3), 1)) is int
    assert arguments.interval("p", [1, 2]) == (1.0, 2.0)
    assert arguments.interval("p", np.array([0.5, 0.5]), 0.0, 1.0) == (0.5, 0.5)
    assert arguments.count_range("c", [np.int64(1), 3], 0, 5) == (1, 3)
    assert arguments.reals("r", ()) == ()
    assert arguments.reals("r", [1, np.float64(2.0)], 0.0) == (1.0, 2.0)
    assert arguments.flag("f", np.bool_(False)) is False


def test_multipath_rows_must_lie_in_the_fix_rows_when_multipath_can_occur():
    from navgym.scenarios import ScenarioDistribution

    ok = ScenarioDistribution(multipath_probability=0.5, multipath_rows=(0, 1))
    arguments.multipath_rows(ok, (0, 1, 2), "rows of the fix")
    bad = ScenarioDistribution(multipath_probability=0.5, multipath_rows=(0, 3))
    with pytest.raises(
        ValueError, match=r"multipath_rows must hold rows of the fix, within \(0, 1, 2\); got \(0, 3\)"
    ):
        arguments.multipath_rows(bad, range(3), "rows of the fix")
    off = ScenarioDistribution(multipath_probability=0.0, multipath_rows=(0, 3))
    arguments.multipath_rows(off, (0, 1, 2), "rows of the fix")  # no multipath: the rows do not matter
