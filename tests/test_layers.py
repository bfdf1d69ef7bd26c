"""The package's architecture: the layers contract of pyproject.toml (import-linter), and no import
cycle between any two modules, imports inside functions included."""
import ast
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SRC = os.path.join(ROOT, "src")


def test_layers_contract_is_kept():
    lint = os.path.join(os.path.dirname(sys.executable), "lint-imports")
    assert os.path.exists(lint), "import-linter is not installed (make venv)"
    r = subprocess.run([lint, "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-6000:] + r.stderr[-3000:]


def modules():
    """``{dotted name: file}`` of every module of meshmill (a package by its ``__init__.py``)."""
    found = {}
    for folder, _, files in os.walk(os.path.join(SRC, "meshmill")):
        for f in files:
            if f.endswith(".py"):
                parts = os.path.relpath(os.path.join(folder, f), SRC)[:-3].split(os.sep)
                found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = os.path.join(folder, f)
    return found


def import_graph():
    """``{module: {imported module: its first import's line}}`` between meshmill's modules."""
    mods = modules()

    def owner(name):  # the module that ``name`` (a module or a name in one) lives in
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for name, path in mods.items():
        with open(path, encoding="utf-8") as fh:
            tree = ast.parse(fh.read(), path)
        package = name if path.endswith("__init__.py") else name.rpartition(".")[0]
        edges = graph.setdefault(name, {})
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                targets = [f"{base}.{a.name}" for a in node.names]
            else:
                continue
            for t in targets:
                m = owner(t)
                if m is not None and m != name:
                    edges[m] = min(edges.get(m, node.lineno), node.lineno)
    return graph


def cycles(graph):
    """One cycle ``[a, b, ..., a]`` per strongly connected group of modules (Tarjan)."""
    index, low, stack, on, groups = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = set()
            while True:
                w = stack.pop()
                on.discard(w)
                group.add(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(group)

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph)))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    found = []
    for group in groups:  # the shortest way from the group's first module back to it
        start = min(group)
        paths, seen = [[start]], {start}
        while paths:
            path = paths.pop(0)
            nxt = [w for w in sorted(graph[path[-1]]) if w in group]
            if start in nxt:
                found.append(path + [start])
                break
            for w in nxt:
                if w not in seen:
                    seen.add(w)
                    paths.append(path + [w])
    return found


def test_import_graph_is_read():
    graph = import_graph()
    assert graph["meshmill.ops.finish"]["meshmill.pathing.verify"] > 0  # a relative import, two levels up
    assert "meshmill.api" in graph["meshmill"]  # inside a function


def test_no_import_cycles():
    graph = import_graph()
    found = ["".join(f"{a} (l.{graph[a][b]}) -> " for a, b in zip(c, c[1:])) + c[-1] for c in cycles(graph)]
    assert not found, "import cycles (the line of each import):\n" + "\n".join(found)


def test_a_cycle_is_found():
    graph = {"a": {"b": 1}, "b": {"c": 2}, "c": {"a": 3, "d": 4}, "d": {"d2": 5}, "d2": {}}
    assert cycles(graph) == [["a", "b", "c", "a"]]
