"""Fixed-point text written by the compiled loop is Python's, character for character, and the CL
writer built on it writes what a move-by-move writer does."""
import dataclasses
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshmill.toolpath.cldata import write_apt
from meshmill.toolpath.decimals import fixed_rows
from meshmill.toolpath.model import Toolpath


def python_rows(values, decimals, prefix, sep):
    return [prefix + sep.join(f"{v:.{d}f}" for v, d in zip(row, decimals)) + "\n" for row in values.tolist()]


def for_python(x, d) -> bool:
    """Whether ``x`` may be left to Python at ``d`` decimals: not finite, too large to scale
    exactly, or its exact value times 10^d within 1e-15 (relative) of a half."""
    if not math.isfinite(x) or abs(x) * 10.0 ** d >= 2.0 ** 52:
        return True
    exact = abs(Fraction(x)) * 10 ** d
    return abs(exact - math.floor(exact) - Fraction(1, 2)) <= Fraction(1e-15) * max(exact, 1)


def is_half(x, d) -> bool:
    return math.isfinite(x) and (abs(Fraction(x)) * 10 ** d) % 1 == Fraction(1, 2)


def lines_of(values, decimals, prefix="GOTO/", sep=", "):
    """Each row's line: the compiled one, or Python's where it leaves the row to Python."""
    text, ends, odd = fixed_rows(values, decimals, prefix, sep)
    wanted = python_rows(values, decimals, prefix, sep)
    got = [w if o else text[a:b].decode() for w, o, a, b in zip(wanted, odd, ends[:-1], ends[1:])]
    assert all(text[a:b] == b"" for a, b, o in zip(ends[:-1], ends[1:], odd) if o)
    return got, wanted, odd


def test_rounding_signs_and_halves_as_python_writes_them():
    tricky = [0.0, -0.0, 1e-300, -1e-300, -4e-7, 4e-7, -5e-7, 0.5, 1.5, 2.5, -2.5, 1 / 128, 3 / 128, -5 / 128,
              0.1, 0.2, 0.3, 1 - 1e-7, -(1 - 1e-7), 9.9999995, 99999.9999995, 1e6, -1e6, 123456.789012345,
              2.0 ** 40 + 0.5, 4503599.6270496, 1e9, 1e17, -1e17, np.nan, np.inf, -np.inf, 0.0000005, 0.0000015]
    for d in (0, 1, 3, 6, 9):
        values = np.array(tricky)[:, None]
        got, wanted, odd = lines_of(values, [d])
        assert got == wanted, d
        # the non-finite, the too large and the exact halves are left to Python, and no others
        assert all(for_python(x, d) for x in values[odd, 0]), d
        assert all(o for x, o in zip(tricky, odd) if not math.isfinite(x) or is_half(x, d)), d
    got, wanted, odd = lines_of(np.array(tricky)[:, None], [18])  # the most decimals
    assert got == wanted
    with pytest.raises(ValueError, match="0 to 18"):
        fixed_rows(np.array([[1e-4]]), [19], "", "")
    # 1/128 = 0.0078125 is a half at 6 decimals (Python: to even, 0.007812): left to Python
    assert fixed_rows(np.array([[1 / 128]]), [6], "", "")[2][0]
    assert fixed_rows(np.array([[1 / 128]]), [7], "", "")[0] == b"0.0078125\n"


@settings(max_examples=300, deadline=None)
@given(st.lists(st.lists(st.floats(-1e7, 1e7, allow_nan=False, width=64), min_size=3, max_size=3), min_size=1,
                max_size=20), st.lists(st.integers(0, 12), min_size=3, max_size=3))
def test_any_finite_numbers_read_as_python_writes_them(rows, decimals):
    got, wanted, odd = lines_of(np.array(rows), decimals, "X", " ")
    assert got == wanted
    assert all(any(for_python(v, d) for v, d in zip(r, decimals)) for r, o in zip(rows, odd) if o)
    assert all(o for r, o in zip(rows, odd) if any(is_half(v, d) for v, d in zip(r, decimals)))


def test_values_on_decimal_grid_lines():
    """Tips at whole mm and at steps of 0.1 mm (CAM grids): no row left to Python at 6 decimals."""
    grid = np.round(np.arange(-5000, 5000) * 0.1, 1)
    got, wanted, odd = lines_of(np.column_stack([grid, grid * 3, -grid]), [6, 6, 9])
    assert got == wanted and not odd.any()


def move_by_move(tp, tools, partno="meshmill"):
    """The CL text, one move after another (the writer's definition)."""
    lines, current, fed = [f"PARTNO/{partno}", "UNITS/MM", "MULTAX/ON"], -1, np.nan
    for t, rapid, tip, axis, f in zip(tp.tool.tolist(), tp.rapid.tolist(), tp.tip.tolist(), tp.axis.tolist(),
                                      tp.feed.tolist()):
        if t != current:
            lines += [tools[t].apt_cutter(), f"LOADTL/{tools[t].number}"]
            if tools[t].rpm > 0:
                lines.append(f"SPINDL/RPM, {tools[t].rpm:.0f}, CLW")
            current, fed = t, np.nan
        if rapid:
            lines.append("RAPID")
        elif f == f and f != fed:
            lines.append(f"FEDRAT/{f:.1f}, MMPM")
            fed = f
        lines.append("GOTO/%.6f, %.6f, %.6f, %.9f, %.9f, %.9f" % (*tip, *axis))
    return "\n".join(lines + ["FINI"]) + "\n"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cl_file_as_written_move_by_move(tmp_path, tools, seed):
    rng = np.random.default_rng(seed)
    n = 400
    tip = np.round(rng.uniform(-50, 50, (n, 3)), rng.integers(0, 7))
    tip[::17] = 1 / 128  # halves at 6 decimals: rows left to Python
    tip[5::23] = -0.0
    axis = rng.normal(size=(n, 3))
    axis[:, 2] = np.abs(axis[:, 2])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    axis[::7] = (0.0, 0.0, 1.0)
    rapid = rng.random(n) < 0.2
    tool = np.repeat(rng.integers(0, len(tools), 5), n // 5)
    feed = rng.choice([np.nan, 300.0, 1200.0, 1200.05], n)
    tools = [dataclasses.replace(t, rpm=8000.0 if k == 1 else t.rpm) for k, t in enumerate(tools)]
    tp = Toolpath(tip, axis, rapid, tool, feed=feed)
    write_apt(tmp_path / "p.cl", tp, tools, partno="part")
    assert (tmp_path / "p.cl").read_text() == move_by_move(tp, tools, "part")
    empty = Toolpath(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, bool), np.zeros(0, np.int64))
    write_apt(tmp_path / "e.cl", empty, tools)
    assert (tmp_path / "e.cl").read_text() == move_by_move(empty, tools)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["", "-", "+"]), st.integers(0, 10 ** 15 - 1), st.integers(0, 22),
                          st.sampled_from(["", " ", "  "])), min_size=1, max_size=30))
def test_plain_decimals_read_as_python_reads_them(items):
    """read_fixed gives the double of Python's ``float`` for every plain decimal (at most 15
    digits, 22 after the point; signs, spaces, leading zeros, -0) bit for bit, from a compiled
    loop (a quotient of two exact doubles, correctly rounded)."""
    from meshmill.toolpath.decimals import read_fixed

    texts = []
    for sign, m, d, pad in items:
        digits = str(m).rjust(d + 1, "0")
        texts.append(pad + sign + (digits[:-d] + "." + digits[-d:] if d else digits) + pad)
    got = read_fixed(",".join(texts), len(texts))
    want = np.array([float(t) for t in texts])
    assert got is not None and np.array_equal(got.view(np.int64), want.view(np.int64))


def test_what_is_not_a_plain_decimal_is_left_to_python():
    """Exponents, 16 significant digits, 23 decimals, empty items, words, tabs, underscores, a
    count that does not match: None (the caller reads them with Python, and says what is wrong)."""
    from meshmill.toolpath.decimals import read_fixed

    for text, count in [("1e5", 1), ("1234567890123456", 1), ("0." + "0" * 22 + "1", 1), ("1,,2", 3), ("", 1),
                        ("-", 1), (".", 1), ("nan", 1), ("inf", 1), ("1\t", 1), ("1_0", 1), ("1,2", 3),
                        ("1,2", 1), ("1.5.2", 1), ("--1", 1), ("1 2", 1), ("é", 1)]:
        assert read_fixed(text, count) is None, text
    assert read_fixed("1234567890.12345, -.5, 7.", 3).tolist() == [1234567890.12345, -0.5, 7.0]
