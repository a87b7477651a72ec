"""Numbers as text (contouring_ros/records/numbers.py): the one place where the cells of every table, report
and CSV file are formatted."""
import math

import numpy as np

from contouring_ros.records.numbers import csv_cell, fixed, median_interval, number, ratio, relative


def test_a_number_keeps_its_significant_digits_and_counts_print_whole():
    assert number(1.23456e-6, scale=1e6) == "1.23"
    assert number(0.000123456, 4) == "0.0001235"
    assert number(1234567, 3) == "1234567" and number(np.int64(1234567)) == "1234567"
    assert number(2.0) == "2" and number(-0.5, 2) == "-0.5"


def test_a_missing_figure_prints_as_the_caller_says_and_infinity_only_where_allowed():
    assert number(None) == number(math.nan) == "-"
    assert number(None, missing="diverged") == "diverged"
    assert number(math.inf) == "inf" and number(-math.inf, finite=True) == "-"


def test_a_csv_cell_has_six_digits_and_is_empty_without_a_finite_figure():
    assert csv_cell(1.234567891e-6, 1e6) == "1.23457"
    assert csv_cell(None) == csv_cell(math.nan) == csv_cell(math.inf) == ""


def test_an_interval_prints_its_median_and_bounds_and_widens_only_where_they_print_alike():
    assert median_interval(2e-6, 1e-6, 3.5e-6, scale=1e6) == "2 [1, 3.5]"
    assert median_interval(1.0, 0.9, math.inf) == "1 [0.9, inf]"
    assert median_interval(math.nan, 0.0, 1.0) == median_interval(None, 0.0, 1.0) == "-"
    assert median_interval(1.0000012, 1.0000011, 1.0000013, narrow_digits=7) == "1.000001 [1.000001, 1.000001]"
    assert median_interval(1.0, 0.5, 2.0, narrow_digits=6) == "1 [0.5, 2]"


def test_a_ratio_is_not_given_against_a_missing_or_zero_reference():
    assert ratio(3.0, 2.0) == "1.5" and ratio(1.0, 3.0, 2) == "0.33"
    assert ratio(1.0, 0.0) == ratio(None, 1.0) == ratio(1.0, None) == ratio(1.0, math.inf) == "-"
    assert relative(3.0, 2.0) == 1.5 and relative(1.0, 0.0) is None and relative(None, 1.0) is None


def test_fixed_decimals_never_print_a_negative_zero():
    assert fixed(0.0012345, 3) == "0.001" and fixed(-0.0004, 3) == "0.000" and fixed(-1.25, 1) == "-1.2"
