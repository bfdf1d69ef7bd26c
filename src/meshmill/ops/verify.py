"""The check of any tool path (``meshmill verify``): gouges beyond the tolerance, shank and holder
collisions and rapids into the stock, certified between the poses
(:mod:`meshmill.pathing.verify`), on one machine or by ranges of moves on a cluster."""
from __future__ import annotations

from ..kernels.backend import solid_kernels
from ..pathing.verify import StockCheck, merge_reports, path_pieces, verify_piece, verify_toolpath


def verify(part, toolpath, tools, tolerance, step, stock, worst=10, device="cpu", client=None, progress=None) -> dict:
    """The report of ``toolpath`` against ``part``, its rapids against ``stock`` (a
    :class:`~meshmill.simulation.stock.Stock`, or None: the part alone); ``client``: a
    ``distributed.Client`` that checks ranges of moves (the same report). ``problem_moves``:
    the moves that fail."""
    say = progress or (lambda stage: None)
    solid, allowance, _ = stock.material(part) if stock is not None else (None, 0.0, 0.0)
    floor = min(part.bounds[0, 2], solid.bounds[0, 2]) if solid is not None else None
    if client is not None:
        from ..cluster import PIECES_PER_WORKER, run_pieces, workers

        pieces = path_pieces(toolpath, PIECES_PER_WORKER * workers(client))
        shared = dict(part=part, floor=floor, stock=solid, allowance=allowance, tools=list(tools), tol=tolerance,
                      step=step, device=device)
        parts = run_pieces(client, verify_piece, shared, pieces, say, "certified check of every move")
        return merge_reports(toolpath, parts, tolerance, step,
                             {**StockCheck(allowance=allowance).summary(), "mesh": solid is not None}, worst)
    say("index")
    check = StockCheck(allowance=allowance, kern=solid_kernels(solid, device) if solid is not None else None)
    kern = solid_kernels(part, device, floor)
    say("certified check of every move")
    return verify_toolpath(kern, toolpath, tools, tolerance, step, worst=worst, stock=check, progress=say)
