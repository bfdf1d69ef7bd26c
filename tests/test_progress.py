"""Long stages done in pieces on one machine: the share done and the time left told, the result
the whole's (issue 23)."""
import numpy as np

from meshmill.geometry import shapes
from meshmill.kernels.backend import solid_kernels
from meshmill.pathing.dropcutter import ToolDrop, drop_refined, drop_refined_pieces
from meshmill.pathing.verify import verify_toolpath
from meshmill.progress import in_pieces, ranges

from test_cluster import TOOLS, zigzag_with_problems


def test_pieces_tell_the_share_done_and_the_time_left(monkeypatch):
    monkeypatch.setattr("meshmill.progress.QUIET_S", 0.0)
    said = []
    out = in_pieces(lambda a, b: b - a, ranges(10, 4), said.append, "stage", weight=lambda a, b: (b - a) ** 2)
    assert out == [2, 3, 3, 2] and len(said) == 4
    shares = [int(s.split(": ")[1].split(" %")[0]) for s in said]
    assert shares == sorted(shares) and shares[-1] == 100 and shares[0] == round(100 * 4 / 26)
    # the time left from the second piece on, at the pace since the first
    assert "left" not in said[0] and all("s left" in s for s in said[1:-1]) and said[-1] == "stage: 100 %"


def test_a_short_stage_is_not_told():
    said = []
    in_pieces(lambda a, b: None, ranges(10, 4), said.append, "stage")
    assert said == []


def test_verify_in_pieces_gives_the_whole_report(monkeypatch):
    monkeypatch.setattr("meshmill.progress.QUIET_S", 0.0)
    part = shapes.post_with_fillet(segments=48)
    tp = zigzag_with_problems(part)
    kern = solid_kernels(part, "cpu")
    said = []
    pieces = verify_toolpath(kern, tp, TOOLS, 0.01, 0.5, progress=said.append)
    whole = verify_toolpath(kern, tp, TOOLS, 0.01, 0.5)
    assert not whole["ok"] and pieces == whole and len(said) > 1


def test_a_raster_dropped_in_pieces_is_the_whole_drop():
    part = shapes.post_with_fillet(segments=48)
    drop = ToolDrop(TOOLS[0], solid_kernels(part, "cpu"), float(part.bounds[0, 2]))
    xy = np.column_stack([np.linspace(-45.0, 45.0, 301), np.full(301, 3.0)])  # over the post's edge and fillet
    assert np.array_equal(drop_refined_pieces(xy, drop, 0.005, 0.01), drop_refined(xy, drop, 0.005, 0.01))
