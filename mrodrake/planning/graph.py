"""Multi-robot graph transition systems: the setting of STyLuS*, P_MAS_TG and LOMAP (no objects, no packing).

Each robot moves on its own weighted directed graph (several robots may share one); a TS state is the tuple
of the robots' vertices (global vertex ids: the graphs' vertices one after the other) and all robots move at
once, each along one edge of its graph (a self-loop lets it stay; ``self_loops`` adds them at cost 0).  The
cost of a step is the sum of the edge weights.  Atomic propositions are predicates: ``all`` (AND) or
``any`` (OR) of clauses "robot r is at one of these vertices".  The NBA reads the label of the source state
of each step (the paper's product; bodies never pass through intermediate labels here).

Task file (YAML, ``format: mrodrake.graph``)::

    format: mrodrake.graph
    name: patrol
    graphs:
      office:                         # GraphML (networkx) or an edge list ("u v [weight]" per line) ...
        file: office.graphml          #   (relative to the YAML file)
        undirected: true              # default true: every edge both ways
        self_loops: true              # default true: robots may stay (cost 0)
      yard:                           # ... or inline edges [u, v] / [u, v, weight] with optional positions
        edges: [[a, b], [b, c, 2.5]]
        positions: {a: [0, 0], b: [1, 0], c: [1, 1]}
    robots:                           # a list, or {count: N, graph: G, initial: [...]} for r1..rN
      - {name: r1, graph: office, initial: "3"}
      - {name: r2, graph: yard, initial: a}
    propositions:
      p1: {all: {r1: ["7", "9"], r2: [c]}}   # r1 at 7 or 9, and r2 at c
      p2: {any: {r1: ["1"], r2: [a]}}        # r1 at 1, or r2 at a
    task: "G F p1 & G F p2"
    planning: {seed: 0, iterations: 2000, p_rand: 0.9, p_new: 0.8}

Edge weights: the ``weight`` (or ``cost``) attribute, else the Euclidean distance of the endpoints' positions
(GraphML node attributes ``x``, ``y``; inline ``positions``), else 1.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import networkx as nx
import numpy as np
import scipy.sparse as sp
import yaml

from mrodrake.errors import UserError
from mrodrake.ts import Navigate, State

FORMAT = "mrodrake.graph"
#: Graphs with at most this many vertices in total keep dense adjacency and weight matrices.
DENSE_VERTICES = 4096


@dataclass(frozen=True)
class Predicate:
    """``mode`` "all" (AND) or "any" (OR) over clauses (robot, allowed vertices as a sorted array)."""

    name: str
    mode: str
    clauses: tuple[tuple[int, np.ndarray], ...]

    def holds(self, s: Sequence[int]) -> bool:
        hits = (bool(np.isin(s[r], vs)) for r, vs in self.clauses)
        return all(hits) if self.mode == "all" else any(hits)


@dataclass
class GraphPlanning:
    """Planner parameters of a graph task (as a scenario's ``planning``)."""

    seed: int = 0
    iterations: int = 2000
    p_rand: float = 0.9
    p_new: float = 0.8


@dataclass
class GraphTask:
    """A loaded graph task: its TS, the task formula (text) and the planner parameters."""

    name: str
    formula: str
    planning: GraphPlanning = field(default_factory=GraphPlanning)


class GraphTS:
    """N robots on weighted graphs (see the module docstring).

    ``graphs``: per graph (name, vertex names, CSR adjacency with weights); ``robot_graph[i]``: robot i's graph;
    ``initial[i]``: robot i's initial vertex (local index in its graph); ``propositions``: name ->
    (mode, {robot index: [local vertex indices]})."""

    #: The NBA reads the source label of each step (:class:`~mrodrake.planning.semantics.SourceWords`).
    reads_source_label = True

    def __init__(self, name: str, robot_names: Sequence[str],
                 graphs: Sequence[tuple[str, Sequence[str], sp.csr_matrix]],
                 robot_graph: Sequence[int], initial: Sequence[int],
                 propositions: Mapping[str, tuple[str, Mapping[int, Sequence[int]]]],
                 planning: GraphPlanning | None = None, formula: str = ""):
        self.scenario = GraphTask(name, formula, planning or GraphPlanning())
        self.name = name
        self.N, self.M = len(robot_names), 0
        self.robot_names = list(robot_names)
        self.object_names: list[str] = []
        self.graph_names = [g[0] for g in graphs]
        self.offsets = np.cumsum([0] + [len(g[1]) for g in graphs])
        single = len(graphs) == 1
        self.region_names = [str(v) if single else f"{g[0]}:{v}" for g in graphs for v in g[1]]
        self.K = int(self.offsets[-1])
        self.robot_graph = [int(g) for g in robot_graph]
        self.initial: State = tuple(int(self.offsets[self.robot_graph[i]] + initial[i]) for i in range(self.N))
        coos = [g[2].tocoo() for g in graphs]
        rows = np.concatenate([c.row + self.offsets[k] for k, c in enumerate(coos)])
        cols = np.concatenate([c.col + self.offsets[k] for k, c in enumerate(coos)])
        data = np.concatenate([c.data for c in coos])
        self.adj = sp.csr_matrix((data, (rows, cols)), shape=(self.K, self.K))
        self.adj.sort_indices()
        pattern = sp.csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(self.K, self.K))
        forward = dict(zip(zip(rows.tolist(), cols.tolist()), data.tolist()))
        self.symmetric = (pattern != pattern.T).nnz == 0 and all(forward[(v, u)] == w for (u, v), w in forward.items())
        self.dense = self.K <= DENSE_VERTICES
        if self.dense:
            self.A = np.zeros((self.K, self.K), dtype=bool)
            self.A[rows, cols] = True
            self.W = np.full((self.K, self.K), np.inf)
            self.W[rows, cols] = data
        keys = rows * self.K + cols
        order = np.argsort(keys)
        self._keys, self._weights = keys[order], data[order]
        self.propositions = list(propositions)
        self.predicates = []
        for pname, (mode, clauses) in propositions.items():
            cl = tuple((int(r), np.sort(np.asarray([self.offsets[self.robot_graph[r]] + v for v in vs],
                                                   dtype=np.int64)))
                       for r, vs in clauses.items())
            self.predicates.append(Predicate(pname, mode, cl))
        self.member = [[(r, np.isin(np.arange(self.K), vs)) for r, vs in p.clauses] for p in self.predicates]
        self._label: dict[State, int] = {}

    # ------------------------------------------------------------------------------------ labels, costs
    def label_mask(self, s: State) -> int:
        """Bit b set iff proposition b holds at s."""
        m = self._label.get(s)
        if m is None:
            m = 0
            for b, (p, mem) in enumerate(zip(self.predicates, self.member)):
                hits = [bool(inside[s[r]]) for r, inside in mem]
                if (all(hits) if p.mode == "all" else any(hits)):
                    m |= 1 << b
            self._label[s] = m
        return m

    def label(self, s: State) -> frozenset[str]:
        m = self.label_mask(s)
        return frozenset(p for b, p in enumerate(self.propositions) if m >> b & 1)

    def weight(self, u: int, v: int) -> float:
        """Weight of edge u → v (inf if there is none)."""
        if self.dense:
            return float(self.W[u, v])
        return float(self.weights(np.array([u]), np.array([v]))[0])

    def has_edges(self, U: np.ndarray, V: np.ndarray) -> np.ndarray:
        """``U[k] → V[k]`` is an edge (arrays broadcast)."""
        if self.dense:
            return self.A[U, V]
        return np.isfinite(self.weights(U, V))

    def weights(self, U: np.ndarray, V: np.ndarray) -> np.ndarray:
        """Weights of the edges ``U[k] → V[k]`` (inf where there is none; arrays broadcast)."""
        if self.dense:
            return self.W[U, V]
        key = np.asarray(U, dtype=np.int64) * self.K + np.asarray(V, dtype=np.int64)
        k = np.minimum(np.searchsorted(self._keys, key), len(self._keys) - 1)
        return np.where(self._keys[k] == key, self._weights[k], np.inf)

    def cost(self, s: State, t: State) -> float:
        return float(sum(self.weight(u, v) for u, v in zip(s, t)))

    def neighbours(self, u: int) -> np.ndarray:
        return self.adj.indices[self.adj.indptr[u]:self.adj.indptr[u + 1]]

    # ------------------------------------------------------------------------------------ transitions
    def is_valid(self, s: State) -> bool:
        return len(s) == self.N and all(self.offsets[g] <= v < self.offsets[g + 1] for v, g in zip(s, self.robot_graph))

    def check_transition(self, s: State, t: State) -> str | None:
        """Why s → t is not a transition (None if it is)."""
        if not self.is_valid(s) or not self.is_valid(t):
            return "a state puts a robot outside its graph"
        for i, (u, v) in enumerate(zip(s, t)):
            if not math.isfinite(self.weight(u, v)):
                return f"robot {self.robot_names[i]} has no edge {self.region_names[u]} -> {self.region_names[v]}"
        return None

    def actions(self, s: State, t: State) -> tuple:
        return tuple(Navigate(i, u, v) for i, (u, v) in enumerate(zip(s, t)) if u != v)

    def successor_states(self, s: State):
        """All successors (product of the robots' out-edges: small systems only)."""
        lists = [self.neighbours(u) for u in s]
        idx = np.zeros(len(lists), dtype=np.int64)
        sizes = [len(x) for x in lists]
        if min(sizes, default=1) == 0:
            return
        while True:
            yield tuple(int(lists[i][idx[i]]) for i in range(len(lists)))
            k = len(lists) - 1
            while k >= 0:
                idx[k] += 1
                if idx[k] < sizes[k]:
                    break
                idx[k] = 0
                k -= 1
            if k < 0:
                return

    def successors(self, s: State):
        for t in self.successor_states(s):
            yield t, self.actions(s, t), self.cost(s, t)

    # ------------------------------------------------------------------------------------ presentation
    def state_dict(self, s: State) -> dict:
        return {"robots": {self.robot_names[i]: self.region_names[v] for i, v in enumerate(s)}, "objects": {},
                "grasps": {}}

    def state_from_dict(self, d: dict) -> State:
        index = {n: k for k, n in enumerate(self.region_names)}
        return tuple(index[d["robots"][n]] for n in self.robot_names)

    def format_action(self, a, style: str = "text") -> str:
        if style == "names":
            return f"navigate {self.robot_names[a.robot]} {self.region_names[a.src]}->{self.region_names[a.dst]}"
        return f"{self.region_names[a.src]} →{a.robot + 1} {self.region_names[a.dst]}"

    def unreachable(self) -> list[str]:
        return []

    def summary(self) -> str:
        return (f"{self.N} robots on {len(self.graph_names)} graph(s) ({self.K} vertices, {self.adj.nnz} edges), "
                f"{len(self.propositions)} propositions")


def graph_matrix(n: int, edges: Sequence[tuple[int, int, float]], undirected: bool, self_loops: bool) -> sp.csr_matrix:
    """CSR adjacency of a graph with ``n`` vertices: the stored entries are the edges (weights may be 0; the
    first weight given for a pair wins)."""
    first: dict[tuple[int, int], float] = {}
    for u, v, c in edges:
        first.setdefault((u, v), float(c))
        if undirected:
            first.setdefault((v, u), float(c))
    if self_loops:
        for u in range(n):
            first.setdefault((u, u), 0.0)
    rows = np.fromiter((u for u, _ in first), dtype=np.int64, count=len(first))
    cols = np.fromiter((v for _, v in first), dtype=np.int64, count=len(first))
    data = np.fromiter(first.values(), dtype=float, count=len(first))
    m = sp.csr_matrix((data, (rows, cols)), shape=(n, n))
    m.sort_indices()
    return m


# ---------------------------------------------------------------------------------------------- loading
def _fail(where: str, what: str) -> UserError:
    return UserError(f"{where}: {what}")


def _read_graph(spec: dict, where: str, base: Path) -> tuple[list[str], list[tuple[str, str, float | None]], dict]:
    """(vertex names, edges (u, v, weight or None), positions) of one graph entry."""
    if not isinstance(spec, dict):
        raise _fail(where, "expected a mapping with 'file' or 'edges'")
    unknown = set(spec) - {"file", "edges", "positions", "undirected", "self_loops", "vertices"}
    if unknown:
        raise _fail(f"{where}.{sorted(unknown)[0]}", "unknown field")
    names: list[str] = [str(v) for v in spec.get("vertices", [])]
    pos: dict[str, tuple[float, float]] = {}
    edges: list[tuple[str, str, float | None]] = []
    if "file" in spec:
        path = base / str(spec["file"])
        if not path.is_file():
            raise _fail(f"{where}.file", f"no such file {path}")
        if path.suffix.lower() == ".graphml":
            try:
                g = nx.read_graphml(path)
            except Exception as e:  # networkx raises several parser errors
                raise _fail(f"{where}.file", f"cannot read GraphML: {e}") from None
            for v, attrs in g.nodes(data=True):
                names.append(str(v))
                if "x" in attrs and "y" in attrs:
                    pos[str(v)] = (float(attrs["x"]), float(attrs["y"]))
            for u, v, attrs in g.edges(data=True):
                w = attrs.get("weight", attrs.get("cost"))
                edges.append((str(u), str(v), None if w is None else float(w)))
        else:
            for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
                line = line.split("#", 1)[0].strip()
                if not line:
                    continue
                parts = line.split()
                if len(parts) not in (2, 3):
                    raise _fail(f"{path}:{n}", "expected 'u v' or 'u v weight'")
                try:
                    w = float(parts[2]) if len(parts) == 3 else None
                except ValueError:
                    raise _fail(f"{path}:{n}", f"weight '{parts[2]}' is not a number") from None
                edges.append((parts[0], parts[1], w))
    elif "edges" in spec:
        if not isinstance(spec["edges"], list):
            raise _fail(f"{where}.edges", "expected a list of [u, v] or [u, v, weight]")
        for k, e in enumerate(spec["edges"]):
            if not isinstance(e, (list, tuple)) or len(e) not in (2, 3):
                raise _fail(f"{where}.edges[{k}]", "expected [u, v] or [u, v, weight]")
            try:
                w = float(e[2]) if len(e) == 3 else None
            except (TypeError, ValueError):
                raise _fail(f"{where}.edges[{k}]", f"weight {e[2]!r} is not a number") from None
            edges.append((str(e[0]), str(e[1]), w))
    else:
        raise _fail(where, "needs 'file' or 'edges'")
    for v, p in (spec.get("positions") or {}).items():
        if not isinstance(p, (list, tuple)) or len(p) != 2:
            raise _fail(f"{where}.positions.{v}", "expected [x, y]")
        pos[str(v)] = (float(p[0]), float(p[1]))
    for u, v, w in edges:
        if w is not None and not (math.isfinite(w) and w >= 0):
            raise _fail(where, f"edge {u} -> {v}: weight must be finite and >= 0, got {w}")
    return names, edges, pos


def graph_ts_from_dict(data: dict, source: str = "graph task", base: Path | None = None) -> GraphTS:
    """A :class:`GraphTS` from a parsed task file (module docstring); UserError naming the field."""
    base = base or Path(".")
    if not isinstance(data, dict):
        raise UserError(f"{source}: expected a mapping at the top level")
    if data.get("format") != FORMAT:
        raise UserError(f"{source}: format: expected '{FORMAT}'")
    unknown = set(data) - {"format", "name", "description", "graphs", "robots", "propositions", "task", "planning"}
    if unknown:
        raise UserError(f"{source}: {sorted(unknown)[0]}: unknown field")
    for key in ("graphs", "robots", "propositions", "task"):
        if key not in data:
            raise UserError(f"{source}: {key}: missing required field")
    if not isinstance(data["graphs"], dict) or not data["graphs"]:
        raise UserError(f"{source}: graphs: expected a non-empty mapping of graph names")
    graphs, index = [], {}
    for gname, spec in data["graphs"].items():
        where = f"{source}: graphs.{gname}"
        names, edges, pos = _read_graph(spec, where, base)
        vid = {}
        for v in names:
            vid.setdefault(v, len(vid))
        for u, v, _ in edges:
            vid.setdefault(u, len(vid))
            vid.setdefault(v, len(vid))
        for v in pos:
            if v not in vid:
                raise _fail(f"{where}.positions.{v}", "not a vertex of the graph")
        triples = []
        for u, v, w in edges:
            if w is None:
                w = math.dist(pos[u], pos[v]) if u in pos and v in pos else 1.0
            triples.append((vid[u], vid[v], w))
        m = graph_matrix(len(vid), triples, bool(spec.get("undirected", True)), bool(spec.get("self_loops", True)))
        index[str(gname)] = (len(graphs), vid)
        graphs.append((str(gname), list(vid), m))
    robots = data["robots"]
    if isinstance(robots, dict):
        count, g, init = robots.get("count"), robots.get("graph"), robots.get("initial")
        if not isinstance(count, int) or count < 1:
            raise UserError(f"{source}: robots.count: expected a positive integer")
        if not isinstance(init, list) or len(init) != count:
            raise UserError(f"{source}: robots.initial: expected a list of {count} vertices")
        robots = [{"name": f"r{i + 1}", "graph": g, "initial": init[i]} for i in range(count)]
    if not isinstance(robots, list) or not robots:
        raise UserError(f"{source}: robots: expected a non-empty list")
    names, rgraph, rinit = [], [], []
    for i, r in enumerate(robots):
        where = f"{source}: robots[{i}]"
        if not isinstance(r, dict) or "name" not in r:
            raise UserError(f"{where}: expected a mapping with name, graph, initial")
        gname = r.get("graph", graphs[0][0] if len(graphs) == 1 else None)
        if str(gname) not in index:
            raise UserError(f"{where}.graph: unknown graph {gname!r} (graphs: {', '.join(index)})")
        gi, vid = index[str(gname)]
        if str(r.get("initial")) not in vid:
            raise UserError(f"{where}.initial: {r.get('initial')!r} is not a vertex of graph {gname}")
        if str(r["name"]) in names:
            raise UserError(f"{where}.name: duplicate robot name {r['name']!r}")
        names.append(str(r["name"]))
        rgraph.append(gi)
        rinit.append(vid[str(r["initial"])])
    props = {}
    if not isinstance(data["propositions"], dict):
        raise UserError(f"{source}: propositions: expected a mapping name -> {{all|any: {{robot: [vertices]}}}}")
    for pname, spec in data["propositions"].items():
        where = f"{source}: propositions.{pname}"
        if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in ("all", "any"):
            raise UserError(f"{where}: expected {{all: {{robot: [vertices]}}}} or {{any: ...}}")
        mode, clauses = next(iter(spec.items()))
        if not isinstance(clauses, dict) or not clauses:
            raise UserError(f"{where}.{mode}: expected a non-empty mapping robot -> list of vertices")
        cl = {}
        for rname, vs in clauses.items():
            if str(rname) not in names:
                raise UserError(f"{where}.{mode}.{rname}: unknown robot")
            i = names.index(str(rname))
            vid = index[graphs[rgraph[i]][0]][1]
            vs = vs if isinstance(vs, list) else [vs]
            bad = [v for v in vs if str(v) not in vid]
            if bad:
                raise UserError(f"{where}.{mode}.{rname}: {bad[0]!r} is not a vertex of graph {graphs[rgraph[i]][0]}")
            cl[i] = [vid[str(v)] for v in vs]
        props[str(pname)] = (mode, cl)
    pl = data.get("planning") or {}
    unknown = set(pl) - {"seed", "iterations", "p_rand", "p_new"}
    if unknown:
        raise UserError(f"{source}: planning.{sorted(unknown)[0]}: unknown field")
    values = {}
    for k, v in pl.items():
        kind = type(getattr(GraphPlanning, k))
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (kind is int and not isinstance(v, int)):
            expected = "an integer" if kind is int else "a number"
            raise UserError(f"{source}: planning.{k}: expected {expected}, got {v!r}")
        values[k] = kind(v)
    if values.get("iterations", 1) < 1 or values.get("seed", 0) < 0:
        raise UserError(f"{source}: planning: iterations must be >= 1 and seed >= 0")
    if not all(0 < values.get(k, 0.5) <= 1 for k in ("p_rand", "p_new")):
        raise UserError(f"{source}: planning: p_rand and p_new must be in (0, 1]")
    planning = GraphPlanning(**values)
    if not isinstance(data["task"], str):
        raise UserError(f"{source}: task: expected an LTL formula (text)")
    return GraphTS(str(data.get("name", Path(source).stem)), names, graphs, rgraph, rinit, props, planning,
                   data["task"])


def is_graph_task(path: str | Path) -> bool:
    """Does the YAML file declare ``format: mrodrake.graph``?  (False for anything unreadable.)"""
    try:
        with open(path, encoding="utf-8") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    return any(line.strip().replace("'", "").replace('"', "") == f"format: {FORMAT}" for line in head.splitlines())


def load_graph_ts(path: str | Path) -> GraphTS:
    """Read a graph task file (module docstring)."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise UserError(f"{path}: cannot read: {e.strerror}") from None
    except yaml.YAMLError as e:
        raise UserError(f"{path}: malformed YAML: {getattr(e, 'problem', e)}") from None
    return graph_ts_from_dict(data, str(path), path.parent)


def graph_ts_from_networkx(graphs: Mapping[str, object], robots: Mapping[str, tuple[str, object]],
                           propositions: Mapping[str, tuple[str, Mapping[str, Sequence]]], name: str = "graph",
                           weight: str = "weight", undirected: bool | None = None, self_loops: bool = True,
                           planning: GraphPlanning | None = None) -> GraphTS:
    """A :class:`GraphTS` from networkx graphs: ``graphs`` name -> (Di)Graph (weights from ``weight``, else the
    Euclidean distance of node attributes ``pos`` = (x, y) or ``x``, ``y``, else 1); ``robots`` name -> (graph name,
    initial node); ``propositions`` name -> ("all" | "any", {robot: [nodes]}).  Undirected networkx graphs give both
    directions (``undirected`` overrides)."""
    gl, index = [], {}
    for gname, g in graphs.items():
        nodes = list(g.nodes)
        vid = {v: k for k, v in enumerate(nodes)}
        pos = {v: d.get("pos", (d["x"], d["y"]) if "x" in d and "y" in d else None)
               for v, d in g.nodes(data=True)}
        triples = []
        for u, v, d in g.edges(data=True):
            w = d.get(weight)
            if w is None:
                w = math.dist(pos[u], pos[v]) if pos.get(u) is not None and pos.get(v) is not None else 1.0
            triples.append((vid[u], vid[v], float(w)))
        und = (not g.is_directed()) if undirected is None else undirected
        index[gname] = (len(gl), vid)
        gl.append((str(gname), [str(v) for v in nodes], graph_matrix(len(nodes), triples, und, self_loops)))
    names = list(robots)
    try:
        rgraph = [index[robots[r][0]][0] for r in names]
        rinit = [index[robots[r][0]][1][robots[r][1]] for r in names]
        props = {p: (mode, {names.index(r): [index[robots[r][0]][1][v] for v in vs] for r, vs in cl.items()})
                 for p, (mode, cl) in propositions.items()}
    except (KeyError, ValueError) as e:
        raise UserError(f"graph task: unknown graph, robot or node {e}") from None
    return GraphTS(name, names, gl, rgraph, rinit, props, planning)


def write_graph_task(ts: GraphTS, path: str | Path) -> None:
    """Write ``ts`` as a task file (module docstring) with one edge list per graph next to it
    (``<stem>.<graph>.edges``: one "u v weight" line per edge, both directions listed)."""
    path = Path(path)
    graphs = {}
    for k, gname in enumerate(ts.graph_names):
        lo, hi = int(ts.offsets[k]), int(ts.offsets[k + 1])
        sub = ts.adj[lo:hi, lo:hi].tocoo()
        vertex_names = ts.region_names[lo:hi]
        local = vertex_names if len(ts.graph_names) == 1 else [n.split(":", 1)[1] for n in vertex_names]
        edge_file = path.with_name(f"{path.stem}.{gname}.edges")
        edge_file.write_text("".join(f"{local[u]} {local[v]} {float(w)!r}\n"
                                     for u, v, w in zip(sub.row, sub.col, sub.data)), encoding="utf-8")
        graphs[gname] = {"file": edge_file.name, "undirected": False, "self_loops": False, "vertices": list(local)}

    def local_name(v: int) -> str:
        name = ts.region_names[v]
        return name if len(ts.graph_names) == 1 else name.split(":", 1)[1]

    robots = [{"name": n, "graph": ts.graph_names[ts.robot_graph[i]], "initial": local_name(ts.initial[i])}
              for i, n in enumerate(ts.robot_names)]
    props = {p.name: {p.mode: {ts.robot_names[r]: [local_name(int(v)) for v in vs] for r, vs in p.clauses}}
             for p in ts.predicates}
    pl = ts.scenario.planning
    data = {"format": FORMAT, "name": ts.name, "graphs": graphs, "robots": robots, "propositions": props,
            "task": ts.scenario.formula,
            "planning": {"seed": pl.seed, "iterations": pl.iterations, "p_rand": pl.p_rand, "p_new": pl.p_new}}
    path.write_text(yaml.safe_dump(data, sort_keys=False, width=120), encoding="utf-8")
