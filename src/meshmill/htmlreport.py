"""One self-contained HTML file that shows what the commands wrote: 3D views of the part, the tool
paths (coloured by tool, rapid moves apart), tool axes, contours, plunge lines and the machined
surface coloured by signed deviation, with the summaries' figures, stage times, a deviation
histogram and the tools' share of the path. plotly.js is embedded once: no server, no internet.

A run folder is what ``finish``, ``raster``, ``waterline``, ``plunge``, ``dexel`` or ``simulate``
wrote (``summary.json`` and its outputs). Large paths and meshes are thinned for display only,
and the report says where.
"""
from __future__ import annotations

import html
import os

import numpy as np

from .errors import InputError
from .runfolder import Run, read_run, summary_path

MAX_PATH_POINTS = 150_000  # per tool path shown; more are thinned (every k-th move)
MAX_MESH_FACES = 150_000  # per mesh shown; more are thinned (every k-th triangle)
AXIS_GLYPHS = 300  # tool-axis glyphs per 5-axis path
AXIS_GLYPH_LENGTH = 0.08  # of the part's diagonal
PATH_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf")
RAPID_COLOUR = "#b0b0b0"


def _thin_mesh(vertices, faces, limit, what, notes):
    """``(vertices, faces)`` for display: at most ``limit`` triangles (every k-th, said in
    ``notes``), and only the vertices they use."""
    if len(faces) > limit:
        k = -(-len(faces) // limit)
        notes.append(f"{what}: 1 in {k} of {len(faces):,} triangles shown")
        faces = faces[::k]
    used, inverse = np.unique(faces, return_inverse=True)
    return vertices[used], inverse.reshape(faces.shape)


def _mesh_trace(go, vertices, faces, name, colour="#c8c8c8", opacity=1.0, intensity=None, **kw):
    # float32 / int32: plotly embeds arrays as binary, and this halves the file (display only)
    vertices, faces = np.asarray(vertices, np.float32), np.asarray(faces, np.int32)
    if intensity is not None:
        intensity = np.asarray(intensity, np.float32)
    return go.Mesh3d(x=vertices[:, 0], y=vertices[:, 1], z=vertices[:, 2], i=faces[:, 0], j=faces[:, 1],
                     k=faces[:, 2], name=name, color=None if intensity is not None else colour, opacity=opacity,
                     intensity=intensity, flatshading=True, showlegend=True,
                     lighting=dict(ambient=0.5, diffuse=0.8, specular=0.1), **kw)


def _polyline(go, points, breaks, name, colour, width=3, dash=None, legendgroup=None, showlegend=True):
    """One Scatter3d trace for many polylines: ``points (k, 3)`` with a gap after every index in
    ``breaks``."""
    if len(points) == 0:
        return None
    p = np.insert(points.astype(np.float32), np.asarray(breaks, np.int64) + 1, np.nan, axis=0)
    return go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="lines", name=name, legendgroup=legendgroup,
                        showlegend=showlegend, line=dict(color=colour, width=width, dash=dash),
                        connectgaps=False, hoverinfo="name")


def _segments(points_a, points_b):
    """Polyline data for separate segments a->b: ``(points, breaks)``."""
    p = np.empty((2 * len(points_a), 3))
    p[0::2] = points_a
    p[1::2] = points_b
    return p, np.arange(1, len(p) - 1, 2)


def _tool_name(run, t):
    return run.tools[t].name if t < len(run.tools) else f"T{t + 1}"


def _path_traces(go, run, notes):
    """Cutting moves per tool and rapid moves; ``(traces, shown points)``."""
    tp = run.toolpath
    k = max(1, -(-len(tp) // MAX_PATH_POINTS))
    if k > 1:
        notes.append(f"tool path: every {k}th of {len(tp):,} points shown")
    idx = np.arange(0, len(tp), k)
    if idx[-1] != len(tp) - 1:
        idx = np.append(idx, len(tp) - 1)
    tip, tool = tp.tip[idx], tp.tool[idx]
    # a move belongs to the point it ends at; a thinned segment is rapid if any move it spans is
    rapid = np.r_[tp.rapid[0], np.logical_or.reduceat(tp.rapid, idx[:-1] + 1)] if len(idx) > 1 else tp.rapid[idx]
    traces = []
    cut_move = ~rapid[1:]
    for t in np.unique(tool):
        sel = np.nonzero(cut_move & (tool[1:] == t))[0]
        if len(sel) == 0:
            continue
        starts = np.r_[0, np.nonzero(sel[1:] != sel[:-1] + 1)[0] + 1]  # consecutive moves share a point
        ends = np.r_[starts[1:], len(sel)]
        pts = np.concatenate([np.vstack([tip[sel[a:b]], tip[sel[b - 1] + 1:sel[b - 1] + 2]]) for a, b in zip(starts, ends)])
        breaks = np.cumsum(ends - starts + 1) - 1
        traces.append(_polyline(go, pts, breaks[:-1], f"{_tool_name(run, t)} cutting", PATH_COLOURS[t % len(PATH_COLOURS)],
                                legendgroup="path"))
    sel = np.nonzero(rapid[1:])[0]
    if len(sel):
        p, br = _segments(tip[sel], tip[sel + 1])
        traces.append(_polyline(go, p, br, "rapid moves", RAPID_COLOUR, width=1, dash="dot", legendgroup="path"))
    return [t for t in traces if t is not None]


def _axis_glyphs(go, run, size):
    tp = run.toolpath
    feed = np.nonzero(~tp.rapid)[0]
    if len(feed) == 0 or np.allclose(tp.axis[feed], [0.0, 0.0, 1.0]):
        return None
    pick = feed[np.linspace(0, len(feed) - 1, min(AXIS_GLYPHS, len(feed))).astype(int)]
    p, br = _segments(tp.tip[pick], tp.tip[pick] + size * tp.axis[pick])
    return _polyline(go, p, br, f"tool axes ({len(pick)} of {len(feed):,})", "#444444", width=2)


def _contour_traces(go, run, notes):
    c = run.contours
    pts, off, ok = c["points"], c["offsets"], c["machinable"].astype(bool)
    closed = c["closed"].astype(bool) if "closed" in c else np.zeros(len(ok), bool)
    k = max(1, -(-len(pts) // MAX_PATH_POINTS))
    if k > 1:
        notes.append(f"contours: 1 in {k} of {len(pts):,} CC points shown")
    out = []
    for flag, name, colour in ((True, "machinable contours", "#2ca02c"), (False, "unmachinable contours", "#d62728")):
        chains = []
        for i in np.nonzero(ok == flag)[0]:
            ch = pts[off[i]:off[i + 1]:k]
            chains.append(np.vstack([ch, ch[:1]]) if closed[i] and len(ch) > 2 else ch)
        if chains:
            lengths = np.cumsum([len(ch) for ch in chains]) - 1
            out.append(_polyline(go, np.vstack(chains), lengths[:-1], f"{name} ({len(chains)})", colour, width=2))
    return out


def _zone_traces(go, run):
    """One marker trace per zone of a ``choose`` run, coloured and named by zone with its cutter."""
    z = run.zones
    rows = {r["zone"]: r for r in run.summary.get("zones", [])}
    out = []
    for zone in np.unique(z["zones"][z["zones"] >= 0]):
        pts = z["points"][z["zones"] == zone]
        r = rows.get(int(zone), {})
        name = f"zone {zone}: {r.get('tool', '?')}, {r.get('azimuth_deg', float('nan')):.0f} deg"
        out.append(go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], mode="markers", name=name,
                                marker=dict(size=2, color=PATH_COLOURS[int(zone) % len(PATH_COLOURS)])))
    return out


def deviation_colours(tol: float):
    """A stepped diverging colour scale over ``[-3 tol, 3 tol]`` whose bands are the tolerance
    classes: gouge below -tol (reds, darker deeper), within ±tol (one pale band), excess above tol
    (blues, darker higher)."""
    e = 1e-6
    return [[0.0, "#67001f"], [1 / 3 - e, "#d6604d"], [1 / 3, "#f7f7f7"], [2 / 3, "#f7f7f7"], [2 / 3 + e, "#4393c3"],
            [1.0, "#053061"]], 3.0 * tol


def _deviation_traces(go, run, notes):
    traces = []
    tol = float(run.deviation.get("tolerance", 0.01)) or 0.01
    scale, lim = deviation_colours(tol)
    if run.machined is not None and run.samples is not None and len(run.machined[1]):
        from scipy.spatial import cKDTree

        v, f = _thin_mesh(*run.machined, MAX_MESH_FACES, "machined surface", notes)
        e = run.samples["e"][cKDTree(run.samples["points"]).query(v)[1]]
        traces.append(_mesh_trace(go, v, f, "machined surface (signed deviation)", intensity=e, colorscale=scale,
                                  cmin=-lim, cmax=lim, colorbar=dict(title="deviation mm", x=1.02,
                                                                     tickvals=[-lim, -tol, 0, tol, lim])))
    gouge_at = run.deviation.get("gouge_at")
    if gouge_at is not None and run.deviation.get("gouge_max", 0) > 0:
        g = np.asarray(gouge_at, float).reshape(1, 3)
        traces.append(go.Scatter3d(x=g[:, 0], y=g[:, 1], z=g[:, 2], mode="markers+text",
                                   marker=dict(size=8, color="#ff00ff", symbol="x"),
                                   text=[f"worst gouge {run.deviation['gouge_max']:.4f} mm"],
                                   name=f"worst gouge ({run.deviation['gouge_max']:.4f} mm)"))
    return traces


def _scene(title, go, traces):
    fig = go.Figure(data=traces)
    fig.update_layout(title=title, height=640, margin=dict(l=0, r=0, t=40, b=0),
                      scene=dict(aspectmode="data", xaxis_title="X mm", yaxis_title="Y mm", zaxis_title="Z mm"),
                      legend=dict(itemsizing="constant", x=0.0, y=1.0, bgcolor="rgba(255,255,255,0.7)"))
    return fig


def run_figures(run: Run) -> list:
    """``[(title, plotly Figure)]`` of one run."""
    try:
        import plotly.graph_objects as go
    except ImportError:
        raise InputError("the HTML report needs plotly: pip install 'meshmill[report]'") from None

    figs, notes = [], run.notes
    base = []
    size = 1.0
    if run.part is not None:
        v, f = _thin_mesh(run.part.vertices, run.part.faces, MAX_MESH_FACES, "part", notes)
        size = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
        opacity = 0.35 if run.kind == "simulate" else 1.0 if run.toolpath is None else 0.55
        base.append(_mesh_trace(go, v, f, "part", opacity=opacity))
    if run.zones is not None:
        figs.append((f"{run.kind}: zones", _scene("zones (cells of the sampling grid)", go, base + _zone_traces(go, run))))
    if run.kind in ("finish", "raster", "waterline", "steep-shallow", "plunge", "choose") and run.toolpath is not None:
        traces = list(base) + _path_traces(go, run, notes)
        glyphs = _axis_glyphs(go, run, AXIS_GLYPH_LENGTH * size)
        if glyphs is not None:
            traces.append(glyphs)
        title = {"plunge": "plunge lines", "finish": "5-axis tool path",
                 "choose": "zigzag per zone"}.get(run.kind, "tool path")
        figs.append((f"{run.kind}: {title}", _scene(f"{run.kind}: {title}", go, traces)))
    if run.contours is not None:
        figs.append((f"{run.kind}: contours", _scene("contours: machinable and not", go, base + _contour_traces(go, run, notes))))
    if run.kind == "simulate" and run.deviation is not None:
        figs.append(("simulate: deviation", _scene("machined surface, signed deviation (mm)", go,
                                                   base + _deviation_traces(go, run, notes))))
        if run.samples is not None and len(run.samples["e"]):
            figs.append(("simulate: histogram", _histogram(go, run)))
    if run.left is not None and len(run.left["area"]):
        figs += _left_figures(go, run, base)
    if run.load is not None and run.toolpath is not None and len(run.load["volume"]) == len(run.toolpath):
        figs += _load_figures(go, run, base)
    if run.kind == "dexel" and run.part is not None:
        figs.append(("dexel: part", _scene("part", go, base)))
    seconds = run.summary.get("seconds") or {k[:-8]: v for k, v in (run.summary.get("index") or {}).items()
                                             if k.endswith("_seconds")}  # dexel: index and casting
    stages = {k: v for k, v in seconds.items() if k != "total" and isinstance(v, (int, float))}
    if stages:
        bar = go.Figure(go.Bar(x=list(stages.values()), y=list(stages.keys()), orientation="h",
                               text=[f"{v:.3g} s" for v in stages.values()], textposition="auto"))
        bar.update_layout(title=f"seconds per stage (total {seconds.get('total', sum(stages.values())):.3g} s)",
                          height=120 + 28 * len(stages), margin=dict(l=120, r=20, t=40, b=30), xaxis_title="s")
        figs.append((f"{run.kind}: stages", bar))
    share = tool_share(run)
    if share:
        pie = go.Figure(go.Pie(labels=[n for n, _ in share.values()], values=[v for _, v in share.values()], hole=0.4,
                               sort=False, marker=dict(colors=[PATH_COLOURS[t % len(PATH_COLOURS)] for t in share])))
        pie.update_layout(title="tools: share of the cutting length (mm)", height=320, margin=dict(t=40, b=10))
        figs.append((f"{run.kind}: tools", pie))
    return figs


LEFT_COLOURS = ("#bdbdbd", "#d62728", "#ff7f0e", "#bcbd22", "#1f77b4", "#9467bd", "#8c564b", "#7f7f7f")
LEFT_POINTS = 20000  # most points of the what-is-left map drawn (the out-of-tolerance ones first)


def _left_figures(go, run, base) -> list:
    """What a job left on the part: the design's samples coloured by the reason they are out of
    tolerance (within tolerance in grey), and the area per reason."""
    left = run.left
    reasons = [str(r) for r in left["reasons"]]
    reason, pts, area = left["reason"].astype(int), left["points"], left["area"]
    out = np.nonzero(reason != 0)[0]
    within = np.nonzero(reason == 0)[0]
    room = max(0, LEFT_POINTS - len(out))
    if len(out) > LEFT_POINTS:
        out = out[:: int(np.ceil(len(out) / LEFT_POINTS))]
        run.notes.append(f"the map of what is left shows every {int(np.ceil(len(reason != 0) / LEFT_POINTS))}th point")
    within = within[:: max(1, int(np.ceil(len(within) / max(room, 1))))] if room else within[:0]
    traces = list(base)
    for k, name in enumerate(reasons):
        sel = np.r_[within, out][reason[np.r_[within, out]] == k]
        if not len(sel):
            continue
        e = left["e"][sel]
        hover = dict(hoverinfo="skip") if k == 0 else dict(
            text=[f"{v:.3f} mm" if np.isfinite(v) else "thick: no dexel end near" for v in e], hoverinfo="text+name")
        traces.append(go.Scatter3d(x=pts[sel, 0].round(3), y=pts[sel, 1].round(3), z=pts[sel, 2].round(3),
                                   mode="markers", name=name, **hover,
                                   marker=dict(size=2 if k == 0 else 3, color=LEFT_COLOURS[k % len(LEFT_COLOURS)])))
    tol = float(run.deviation.get("tolerance", 0.01)) if run.deviation else 0.01
    figs = [("job: what is left", _scene(f"what is left on the part (over ±{tol:g} mm) and why", go, traces))]
    sums = [float(area[reason == k].sum()) for k in range(len(reasons))]
    bar = go.Figure(go.Bar(x=sums, y=reasons, orientation="h", marker=dict(color=list(LEFT_COLOURS[:len(reasons)])),
                           text=[f"{v:.0f} mm²" for v in sums], textposition="auto"))
    bar.update_layout(title=f"the design's surface by what is left on it ({sum(sums):.0f} mm²)",
                      height=120 + 28 * len(reasons), margin=dict(l=200, r=20, t=40, b=30), xaxis_title="mm²")
    figs.append(("job: area per reason", bar))
    return figs


def _load_figures(go, run, base) -> list:
    """The load along the path (the moves in material coloured by the spindle power, else the
    removal rate) and, per tool, a histogram of the radial width and of the power."""
    load, tp = run.load, run.toolpath
    cut = np.asarray(load["in_material"], bool)
    if not cut.any():
        return []
    key, unit = ("power", "kW") if np.isfinite(load["power"][cut]).any() else ("rate", "mm³/min")
    value = load[key]
    pts = tp.tip[cut]
    marker = dict(size=2.5, color=value[cut], colorscale="Turbo", colorbar=dict(title=unit), showscale=True)
    trace = go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], mode="markers", marker=marker,
                         name=f"moves in material ({key})",
                         text=[f"ap {a:.2f} ae {e:.2f} mm, {v:.3g} {unit}" for a, e, v in
                               zip(load["ap"][cut], load["ae"][cut], value[cut])], hoverinfo="text")
    figs = [(f"{run.kind}: load", _scene(f"load of every move in material ({key}, {unit})", go, base + [trace]))]
    for t in np.unique(tp.tool[cut]):
        mine = cut & (tp.tool == t)
        fig = go.Figure()
        for field, name in (("ae", "radial width (mm)"), ("ap", "axial depth (mm)"), (key, f"{key} ({unit})")):
            v = load[field][mine]
            v = v[np.isfinite(v)]
            if len(v):
                counts, edges = np.histogram(v, bins=40)
                fig.add_trace(go.Bar(x=0.5 * (edges[1:] + edges[:-1]), y=counts, width=np.diff(edges), name=name,
                                     opacity=0.7))
        fig.update_layout(title=f"tool {_tool_name(run, t)}: {int(mine.sum()):,} moves in material", barmode="overlay",
                          height=320, yaxis_title="moves", margin=dict(t=40, b=40))
        figs.append((f"{run.kind}: load of {_tool_name(run, t)}", fig))
    return figs


def _histogram(go, run):
    e = run.samples["e"]
    tol = float(run.deviation.get("tolerance", 0.01))
    counts, edges = np.histogram(e, bins=80)  # binned here: the file holds 80 bars, not every value
    fig = go.Figure(go.Bar(x=0.5 * (edges[1:] + edges[:-1]), y=counts, width=np.diff(edges), marker_color="#4393c3",
                           name="dexel ends"))
    for x in (-tol, tol):
        fig.add_vline(x=x, line_dash="dash", line_color="#d6604d")
    fig.update_layout(title=f"signed deviation of {len(e):,} dexel ends (mm; dashed: ±{tol:g} mm)",
                      height=320, xaxis_title="mm", yaxis_title="count", margin=dict(t=40, b=40))
    return fig


def tool_share(run: Run) -> dict:
    """``{tool index: (name, cutting length mm)}`` from the tool path."""
    tp = run.toolpath
    if tp is None or len(tp) < 2:
        return {}
    seg = np.linalg.norm(np.diff(tp.tip, axis=0), axis=1)
    out = {}
    for t in np.unique(tp.tool):
        sel = (~tp.rapid[1:]) & (tp.tool[1:] == t)
        if sel.any():
            out[int(t)] = (_tool_name(run, t), round(float(seg[sel].sum()), 3))
    return out


def _flat(d, prefix=""):
    """Scalar entries of a nested summary as ``(key path, value)`` rows."""
    rows = []
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            rows += _flat(v, key + ".")
        elif isinstance(v, list):
            if v and all(not isinstance(x, (dict, list)) for x in v) and len(v) <= 12:
                rows.append((key, ", ".join(str(x) for x in v)))
            else:
                rows.append((key, f"{len(v)} entries"))
        else:
            rows.append((key, f"{v:.6g}" if isinstance(v, float) else str(v)))
    return rows


def _table(rows):
    body = "".join(f"<tr><td>{html.escape(k)}</td><td>{html.escape(v)}</td></tr>" for k, v in rows)
    return f"<table class='kv'><tbody>{body}</tbody></table>"


def write_report(folders: list[str], out: str, progress=None) -> dict:
    """Write the report of ``folders`` to ``out``; returns what it holds (runs, views, notes)."""
    try:
        import plotly
        from plotly.offline import get_plotlyjs
    except ImportError:
        raise InputError("the HTML report needs plotly: pip install 'meshmill[report]'") from None

    say = progress or (lambda _: None)
    for f in folders:  # every folder checked before any progress: a bad one is one line
        summary_path(f)
    runs, meshes = [], {}
    for f in folders:
        say(f"read {f}")
        runs.append(read_run(f, meshes))
    sections, info = [], {"file": os.path.abspath(out), "runs": []}
    div = 0
    for run in runs:
        say(f"views of {run.folder}")
        figs = run_figures(run)
        parts = [f"<h2>{html.escape(run.kind)} — {html.escape(os.path.abspath(run.folder))}</h2>"]
        parts += [f"<p class='note'>{html.escape(n)}</p>" for n in run.notes]
        for title, fig in figs:
            div += 1
            parts.append(fig.to_html(full_html=False, include_plotlyjs=False, div_id=f"view{div}",
                                     config={"displaylogo": False, "responsive": True}))
        parts.append("<h3>summary</h3>" + _table(_flat(run.summary)))
        if run.deviation is not None:
            parts.append("<h3>deviation</h3>" + _table(_flat(run.deviation)))
        sections.append("<section>" + "\n".join(parts) + "</section>")
        info["runs"].append({"folder": os.path.abspath(run.folder), "kind": run.kind,
                             "views": [t for t, _ in figs], "notes": list(run.notes)})
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>meshmill report</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 1.5em; color: #222; }}
section {{ border-top: 2px solid #ccc; margin-top: 2em; }}
table.kv {{ border-collapse: collapse; font-size: 0.9em; }}
table.kv td {{ border: 1px solid #ddd; padding: 2px 8px; }}
table.kv td:first-child {{ color: #555; }}
p.note {{ color: #a15c00; }}
</style>
<script type="text/javascript">{get_plotlyjs()}</script>
</head><body>
<h1>meshmill report</h1>
<p>{len(runs)} run(s); plotly {plotly.__version__}, embedded: this file needs no server and no internet.
Drag to turn a view, scroll to zoom, click a legend entry to hide it.</p>
{''.join(sections)}
</body></html>
"""
    try:
        with open(out, "w", encoding="utf-8") as fh:
            fh.write(page)
    except OSError as exc:
        raise InputError(f"{out}: cannot write ({exc.strerror})") from None
    info["views"] = div
    info["bytes"] = os.path.getsize(out)
    return info
