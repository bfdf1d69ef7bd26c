"""Compare the files two runs wrote (e.g. `make demo` before and after a change), timing aside.

    .venv/bin/python bench/compare_runs.py BEFORE_FOLDER AFTER_FOLDER

Tool paths, programs, meshes and tool tables must be byte-identical; JSON files equal once the
wall-time fields are removed (``seconds``, ``*_seconds``, ``bytes`` of the report); .npz files
array by array; the HTML report equal once its wall-time figures are removed (and its summary
tables compared as sets of rows, as the JSON files are compared as dicts). Prints one line a
file and exits 1 when any differs.
"""
from __future__ import annotations

import json
import os
import re
import sys

import numpy as np

TIMING_KEYS = re.compile(r"^(seconds|.*_seconds|bytes)$")


def _strip(value):
    """``value`` without its wall-time fields."""
    if isinstance(value, dict):
        return {k: _strip(v) for k, v in value.items() if not TIMING_KEYS.match(k)}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def _html(path):
    """The report's text with the figures that depend on wall time removed: the summaries' seconds
    and the stage bar charts."""
    text = open(path, encoding="utf-8").read()
    text = re.sub(r'"?(seconds|[a-z_]*_seconds)"?(\s*[:=]\s*|</td><td>)("[^"]*"|[-0-9.e+]+|\{[^{}]*\})', r"\1=T", text)
    text = re.sub(r"seconds\.[a-z_]+</td><td>[-0-9.e+]+", "seconds=T", text)
    text = re.sub(r'\[\{"orientation":"h","text":\[[^\]]*\],"textposition":"auto","x":\[[^\]]*\](,"y":\[[^\]]*\])?',
                  "STAGES", text)
    # the stage chart (its bars named after the summary's seconds) grows with its number of stages
    text = re.sub(r'<div style="height:\d+px; width:100%;">((?:(?!</script>).)*?STAGES)', r"<div>\1", text, flags=re.S)
    text = re.sub(r"seconds per stage \(total [-0-9.e+]+ s\)", "seconds per stage", text)
    text = re.sub(r'("text":"seconds per stage"\},"height":)\d+', r"\1T", text)
    text = text.replace("<tr><td>seconds=T</td></tr>", "")
    # a summary's table in the order of its keys: compared as the JSON files are, whatever the order
    text = re.sub(r"<table class='kv'>.*?</table>",
                  lambda m: "<table>" + "".join(sorted(re.findall(r"<tr>.*?</tr>", m.group(0)))) + "</table>", text,
                  flags=re.S)
    return re.sub(r"\d+\.\d+ MB", "MB", text)


def same(a, b) -> str:
    """"" when the files ``a`` and ``b`` agree, else what differs."""
    ext = os.path.splitext(a)[1].lower()
    if ext == ".json":
        x, y = _strip(json.load(open(a))), _strip(json.load(open(b)))
        return "" if x == y else "JSON differs"
    if ext == ".npz":
        with np.load(a) as x, np.load(b) as y:
            if sorted(x.files) != sorted(y.files):
                return f"arrays {sorted(x.files)} != {sorted(y.files)}"
            bad = [k for k in x.files if not np.array_equal(x[k], y[k], equal_nan=x[k].dtype.kind == "f")]
            return f"arrays differ: {bad}" if bad else ""
    if ext == ".html":
        return "" if _html(a) == _html(b) else "report differs beyond its timing"
    return "" if open(a, "rb").read() == open(b, "rb").read() else "bytes differ"


def main(argv):
    before, after = argv
    files = sorted({os.path.relpath(os.path.join(d, f), root) for root in (before, after)
                    for d, _, fs in os.walk(root) for f in fs})
    bad = 0
    for rel in files:
        a, b = os.path.join(before, rel), os.path.join(after, rel)
        why = "only in one run" if not (os.path.exists(a) and os.path.exists(b)) else same(a, b)
        bad += bool(why)
        print(f"{'DIFF' if why else 'same'}  {rel}{'  ' + why if why else ''}")
    print(f"{len(files) - bad} of {len(files)} files the same" + ("" if not bad else f"; {bad} differ"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
