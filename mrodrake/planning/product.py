"""Product Büchi automaton PBA = TS ⊗ NBA (paper Sec. III-B, Def. 6), on the fly or explicit.

A product state is a pair ``(s, q)`` of a TS state and an NBA state.  The paper's product reads the label
of the source state, (s, q) → (s', q') iff s → s' and q' ∈ δ(q, L(s)); ours reads the word that sequential
execution produces (:mod:`mrodrake.planning.semantics`), which is the paper's reading on every step that
moves no body across a rim the task mentions.  The cost of a product transition is χ(s, s') and the
accepting product states are ``Π_s × F``.

The module also holds the NBA preprocessing shared by the planners:

* :func:`prune_nba` drops the guard cubes that no single TS label can satisfy (an entity in two regions
  at once, an entity in no region, entities that cannot all fit in one region, an entity fixed by the
  caller somewhere else), which is step (1) of STyLuS* (Kantaros & Zavlanos 2020); with ``transit=True``
  it keeps the cubes that a letter of an executed word satisfies while an entity is between regions (the
  planners read executed words, so they prune with ``transit=True``);
* :func:`accepting_on_cycle` and :func:`hop_distances` give the accepting states that lie on a cycle
  of the pruned automaton and each state's hop distance to them (edges of weight 1).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components, dijkstra

from mrodrake.logic.nba import NBA
from mrodrake.planning.semantics import ExecutedWords
from mrodrake.ts import ExplicitTS, State, TransitionSystem

Node = tuple  # (TS state, NBA state)


# ------------------------------------------------------------------------------------------ guard cubes
@dataclass(frozen=True)
class CubeGoal:
    """What a guard cube ``(pos, neg)`` over the TS propositions asks of a label.

    ``required[e]``: region where entity ``e`` (robots ``0..N-1``, then objects) must be;
    ``forbidden[e]``: bitmask of regions where ``e`` must not be.
    """

    pos: int
    neg: int
    required: Mapping[int, int]
    forbidden: Mapping[int, int]


def decode_cube(ts: TransitionSystem, pos: int, neg: int) -> tuple[dict[int, list[int]], dict[int, int]]:
    """Positive regions per entity (a list: more than one is a contradiction) and forbidden-region masks."""
    K = ts.K
    full = (1 << K) - 1
    required: dict[int, list[int]] = {}
    forbidden: dict[int, int] = {}
    m, b = pos, 0
    while m:
        if m & 1:
            required.setdefault(b // K, []).append(b % K)
        m >>= 1
        b += 1
    for e in range((neg.bit_length() + K - 1) // K):
        f = (neg >> (e * K)) & full
        if f:
            forbidden[e] = f
    return required, forbidden


def cube_goal(ts: TransitionSystem, pos: int, neg: int) -> CubeGoal:
    """The :class:`CubeGoal` of a feasible cube (see :func:`cube_infeasibility`)."""
    req, forb = decode_cube(ts, pos, neg)
    return CubeGoal(pos, neg, {e: ks[0] for e, ks in req.items()}, forb)


def entity_radius(ts: TransitionSystem, e: int) -> float:
    return ts.robot_radius[e] if e < ts.N else ts.object_radius[e - ts.N]


def cube_infeasibility(ts: TransitionSystem, pos: int, neg: int,
                       fixed: Mapping[int, int] | None = None, transit: bool = False) -> str | None:
    """Why no TS label satisfies the cube ``(pos, neg)`` (``None`` if some label might).

    A label puts every entity in exactly one region, so a cube is infeasible if it puts an entity in two
    regions, forbids all regions of an entity, contradicts itself, or asks for entities that cannot fit
    together in one region (necessary area condition: a valid region holds disjoint disks of radius
    r_D + spacing/2 inside radius R − spacing/2, and a team's covering disk holds its members, so
    Σ r_e² ≤ (R − spacing/2)²).  ``fixed`` maps entities to the only region they can ever be in.
    ``transit=True`` judges letters of executed words instead of state labels: an entity that is not fixed
    may be in no region (between two regions, :mod:`~mrodrake.planning.semantics`).
    """
    if pos & neg:
        return "a proposition is required both true and false"
    K = ts.K
    full = (1 << K) - 1
    req, forb = decode_cube(ts, pos, neg)
    names = ts.robot_names + ts.object_names
    n_ent = ts.N + ts.M
    for e, ks in req.items():
        if e >= n_ent:
            return "a proposition outside the TS"
        if len(ks) > 1:
            return f"{names[e]} would be in two regions at once"
    for e, f in forb.items():
        if e < n_ent and f == full and not (transit and e not in (fixed or {})):
            return f"{names[e]} would be in no region"
    if fixed:
        for e, k in fixed.items():
            if e in req and req[e][0] != k:
                return f"{names[e]} cannot leave region {ts.region_names[k]}"
            if forb.get(e, 0) >> k & 1:
                return f"{names[e]} cannot leave region {ts.region_names[k]}"
    per_region: dict[int, float] = {}
    for e, ks in req.items():
        per_region[ks[0]] = per_region.get(ks[0], 0.0) + entity_radius(ts, e) ** 2
    for k, area in per_region.items():
        if area > (ts.region_radius[k] - 0.5 * ts.spacing) ** 2 + 1e-12:
            return f"the entities required in region {ts.region_names[k]} cannot fit in it"
    return None


def prune_nba(nba: NBA, ts: TransitionSystem, fixed: Mapping[int, int] | None = None,
              transit: bool = False) -> NBA:
    """The NBA without guard cubes that no TS label can satisfy (STyLuS* step 1).

    The result accepts exactly the same TS traces (every dropped cube is false on every TS label), and
    it keeps the state numbering.  ``fixed`` (entity -> region) additionally assumes entities that can
    never move (e.g. objects no team is powerful enough to transport); ``transit`` as in
    :func:`cube_infeasibility` (then the result accepts the same executed words).
    """
    if tuple(nba.ap) != tuple(ts.propositions):
        raise ValueError("the NBA must be over the TS propositions (use nba.with_ap(ts.propositions))")
    edges = []
    for row in nba.edges:
        new_row = []
        for guard, dst in row:
            cubes = [(p, n) for p, n in guard if cube_infeasibility(ts, p, n, fixed, transit) is None]
            if cubes:
                new_row.append((cubes, dst))
        edges.append(new_row)
    return NBA(nba.ap, nba.initial, nba.accepting, edges)


def nba_graph(nba: NBA) -> list[list[int]]:
    """Successor lists of the NBA's state graph (edges with a non-empty guard)."""
    return [[dst for _, dst in row] for row in nba.edges]


def _reverse(succ: Sequence[Sequence[int]]) -> list[list[int]]:
    pred: list[list[int]] = [[] for _ in succ]
    for q, row in enumerate(succ):
        for d in row:
            pred[d].append(q)
    return pred


def _bfs(adj: Sequence[Sequence[int]], sources: Sequence[int]) -> list[float]:
    dist = [float("inf")] * len(adj)
    todo = deque()
    for s in sources:
        if dist[s] != 0:
            dist[s] = 0
            todo.append(s)
    while todo:
        u = todo.popleft()
        for v in adj[u]:
            if dist[v] == float("inf"):
                dist[v] = dist[u] + 1
                todo.append(v)
    return dist


def accepting_on_cycle(nba: NBA) -> frozenset[int]:
    """Accepting states that reach themselves by a non-empty path (the only useful ones in a lasso)."""
    succ = nba_graph(nba)
    out = set()
    for f in nba.accepting:
        reach = _bfs(succ, succ[f])
        if reach[f] < float("inf"):
            out.add(f)
    return frozenset(out)


def hop_distances(nba: NBA, targets: Sequence[int]) -> list[float]:
    """Minimum number of NBA edges from each state to ``targets`` (0 on targets, inf if unreachable)."""
    return _bfs(_reverse(nba_graph(nba)), list(targets))


def hop_distances_from(nba: NBA, source: int) -> list[float]:
    """Minimum number of NBA edges from ``source`` to each state (0 at ``source``)."""
    return _bfs(nba_graph(nba), [source])


def cycle_distances(nba: NBA, root: int) -> list[float]:
    """Minimum number of NBA edges (at least one) from each state back to ``root`` (suffix trees)."""
    succ = nba_graph(nba)
    pred = _reverse(succ)
    to_pred = _bfs(pred, pred[root]) if pred[root] else [float("inf")] * len(succ)
    return [d + 1 for d in to_pred]


def useful_states(nba: NBA) -> frozenset[int]:
    """NBA states reachable from the initial state that can reach an accepting state on a cycle."""
    succ = nba_graph(nba)
    fwd = _bfs(succ, [nba.initial])
    back = hop_distances(nba, sorted(accepting_on_cycle(nba)))
    return frozenset(q for q in range(nba.num_states) if fwd[q] < float("inf") and back[q] < float("inf"))


def restrict_nba(nba: NBA, keep) -> NBA:
    """The NBA with every edge into or out of a state outside ``keep`` removed (numbering kept)."""
    keep = set(keep)
    edges = [[(g, d) for g, d in row if q in keep and d in keep] for q, row in enumerate(nba.edges)]
    return NBA(nba.ap, nba.initial, nba.accepting, edges)


def planning_nba(nba: NBA, ts: TransitionSystem) -> NBA:
    """The NBA the planners search: pruned on executed words and restricted to its useful states (the same
    executed words are accepted; state numbering kept)."""
    pruned = prune_nba(nba, ts, transit=True)
    return restrict_nba(pruned, useful_states(pruned))


# ------------------------------------------------------------------------------------------- on the fly
class Product:
    """TS ⊗ NBA on the executed-word semantics (:mod:`mrodrake.planning.semantics`), implicit successors.

    (s, q) → (s', q') iff s → s' in the TS and some execution order of the step's actions takes the NBA
    from q to q' for every crossing interleaving; the NBA must be over ``ts.propositions`` and
    ``relevant`` is the task's AP_φ mask (:func:`~mrodrake.planning.semantics.relevant_mask`).  Without a
    crossing that AP_φ can see this is the paper's q' ∈ δ(q, L(s))."""

    def __init__(self, ts: TransitionSystem, nba: NBA, relevant: int):
        if tuple(nba.ap) != tuple(ts.propositions):
            raise ValueError("the NBA must be over the TS propositions (use nba.with_ap(ts.propositions))")
        self.ts, self.nba = ts, nba
        self.words = ExecutedWords(ts, nba, relevant)

    @property
    def initial(self) -> Node:
        return (self.ts.initial, self.nba.initial)

    def is_accepting(self, node: Node) -> bool:
        return node[1] in self.nba.accepting

    def nba_successors(self, s: State, q: int, t: State) -> list[int]:
        """NBA states q' of the product edges (s, q) → (t, q')."""
        return sorted(self.words.successors(q, s, t))

    def successors(self, node: Node) -> Iterator[tuple[Node, float]]:
        """All product successors with their cost χ (enumerates the TS successors: small systems only)."""
        s, q = node
        for t in self.ts.successor_states(s):
            c = self.ts.cost(s, t)
            for q2 in self.nba_successors(s, q, t):
                yield (t, q2), c

    def is_transition(self, a: Node, b: Node) -> bool:
        """(s, q) → (s', q') by the TS rules (re-derived) and the executed-word semantics."""
        return self.ts.check_transition(a[0], b[0]) is None and b[1] in self.words.successors(a[1], a[0], b[0])

    def cost(self, a: Node, b: Node) -> float:
        return self.ts.cost(a[0], b[0])

    def build(self, ets: ExplicitTS | None = None, some: bool = False) -> ExplicitProduct:
        """The product over the reachable TS as a CSR graph (``some``: the over-approximation,
        :class:`ExplicitProduct`)."""
        return ExplicitProduct.build(self, ets, some)


# ------------------------------------------------------------------------------------------- explicit
@dataclass
class ExplicitProduct:
    """The product over all TS states of ``ets`` as a CSR graph: node ``v = u·Q + q`` is (TS state row
    ``u`` of ``ets``, NBA state ``q``); ``initial`` is the initial product node (``ets`` row 0 is the TS's
    initial state).  Nodes unreachable from ``initial`` are kept (they have no effect on searches from it).

    ``some=False``: the planning product (an edge reaches q' for every crossing interleaving of some
    order).  ``some=True``: the over-approximation (some order and some interleaving reach q',
    :meth:`~mrodrake.planning.semantics.ExecutedWords.some_matrix_for`); ``accepting_edges`` then marks the
    edges whose NBA run passes an accepting state inside the step."""

    product: Product
    ets: ExplicitTS
    graph: sp.csr_matrix
    accepting_edges: sp.csr_matrix | None = None

    @property
    def Q(self) -> int:
        return self.product.nba.num_states

    @property
    def initial(self) -> int:
        return self.product.nba.initial

    @property
    def num_nodes(self) -> int:
        return self.graph.shape[0]

    @property
    def num_edges(self) -> int:
        return self.graph.nnz

    def node(self, v: int) -> Node:
        u, q = divmod(int(v), self.Q)
        return (self.ets.state(u), q)

    def accepting_mask(self) -> np.ndarray:
        acc = np.zeros(self.Q, dtype=bool)
        acc[list(self.product.nba.accepting)] = True
        return np.tile(acc, self.ets.num_states)

    def reachable(self) -> np.ndarray:
        """Boolean mask of the nodes reachable from the initial node."""
        order = breadth_first_order(self.graph, self.initial, directed=True, return_predecessors=False)
        mask = np.zeros(self.num_nodes, dtype=bool)
        mask[order] = True
        return mask

    def has_accepting_cycle(self) -> bool:
        """Does a node reachable from the initial node lie on a cycle through an accepting node or an
        accepting edge?"""
        reach = self.reachable()
        _, comp = connected_components(self.graph, directed=True, connection="strong")
        sizes = np.bincount(comp)
        acc = self.accepting_mask() & reach
        cand = np.flatnonzero(acc)
        ind, ptr = self.graph.indices, self.graph.indptr
        if np.any(sizes[comp[cand]] > 1) or any(v in ind[ptr[v]:ptr[v + 1]] for v in cand):
            return True
        if self.accepting_edges is not None and self.accepting_edges.nnz:
            E = self.accepting_edges.tocoo()
            on = reach[E.row] & (comp[E.row] == comp[E.col])
            return bool(on.any())
        return False

    @staticmethod
    def build(product: Product, ets: ExplicitTS | None = None, some: bool = False) -> ExplicitProduct:
        """Vectorised construction.  Every TS edge u → v gets a *move*: edges whose step crosses no rim
        AP_φ mentions share the move of their source label (δ(q, L(u))); the others get the move of their
        executed-word key, computed once per distinct (source label, crossings) among them.  Row (u, q) then
        holds (v, q') for every TS edge u → v and every q' of its move, with cost χ(u, v)."""
        ts, nba, words = product.ts, product.nba, product.words
        if ets is None:
            ets = ts.build()
        S, Q = ets.num_states, nba.num_states
        src = np.repeat(np.arange(S, dtype=np.int64), np.diff(ets.indptr))
        dst = ets.targets.astype(np.int64)
        n_ent = ts.N + ts.M
        pos = ets.states[:, :n_ent]
        uniq, label_of = np.unique(pos, axis=0, return_inverse=True)
        label_of = label_of.ravel()
        matrices, flags = [], []
        none = np.zeros((Q, Q), dtype=bool)
        for lid in range(len(uniq)):
            mask = 0
            for e, k in enumerate(uniq[lid]):
                mask |= 1 << (e * ts.K + int(k))
            matrices.append(words.matrix_for(mask & words.relevant, ()))
            flags.append(none)
        move = label_of[src].astype(np.int64)
        A, B = ets.states[src], ets.states[dst]
        vis = words.visible(A, B)
        if vis.any():
            idx = np.flatnonzero(vis)
            rel_ent = np.flatnonzero(words.entity_region.any(axis=1))
            cols = np.concatenate([A[idx][:, rel_ent], B[idx][:, rel_ent], A[idx][:, n_ent:]], axis=1)
            keys, inv = np.unique(cols, axis=0, return_inverse=True)
            inv = inv.ravel()
            first = np.full(len(keys), -1, dtype=np.int64)
            first[inv[::-1]] = idx[::-1]
            base = len(matrices)
            for e in first:
                s_, t_ = ets.state(int(src[e])), ets.state(int(dst[e]))
                if some:
                    R, F = words.some_matrix(s_, t_)
                    matrices.append(R)
                    flags.append(F)
                else:
                    matrices.append(words.matrix(s_, t_))
                    flags.append(none)
            move[idx] = base + inv
        Mv = np.stack(matrices) if matrices else np.zeros((0, Q, Q), dtype=bool)
        Fv = np.stack(flags) if some and flags else None
        rows_all, cols_all, data_all, acc_rows, acc_cols = [], [], [], [], []
        chunk = max(1024, (1 << 24) // max(1, Q * Q))  # bounds the (edges, Q, Q) temporary to ~16 MB
        for lo in range(0, len(src), chunk):
            hi = min(len(src), lo + chunk)
            e_move = Mv[move[lo:hi]]  # (edges, Q, Q)
            e_ix, q, q2 = np.nonzero(e_move)
            e_ix = e_ix + lo
            rows_all.append(src[e_ix] * Q + q)
            cols_all.append(dst[e_ix] * Q + q2)
            data_all.append(ets.costs[e_ix])
            if Fv is not None and vis[lo:hi].any():
                f_ix, fq, fq2 = np.nonzero(Fv[move[lo:hi]])
                f_ix = f_ix + lo
                acc_rows.append(src[f_ix] * Q + fq)
                acc_cols.append(dst[f_ix] * Q + fq2)
        rows = np.concatenate(rows_all) if rows_all else np.zeros(0, dtype=np.int64)
        cols = np.concatenate(cols_all) if cols_all else np.zeros(0, dtype=np.int64)
        data = np.concatenate(data_all) if data_all else np.zeros(0)
        if len(rows) >= 2**31 - 1:
            raise MemoryError(f"explicit product too large ({len(rows)} transitions)")
        graph = sp.csr_matrix((data, (rows, cols)), shape=(S * Q, S * Q))
        acc_edges = None
        if some:
            ar = np.concatenate(acc_rows) if acc_rows else np.zeros(0, dtype=np.int64)
            ac = np.concatenate(acc_cols) if acc_cols else np.zeros(0, dtype=np.int64)
            acc_edges = sp.csr_matrix((np.ones(len(ar), dtype=np.int8), (ar, ac)), shape=(S * Q, S * Q))
        return ExplicitProduct(product, ets, graph, acc_edges)


# ------------------------------------------------------------------------------------------- lassos
def _path(pred: np.ndarray, src: int, dst: int) -> list[int]:
    out = [dst]
    while out[-1] != src:
        p = int(pred[out[-1]])
        if p < 0:
            raise RuntimeError("broken predecessor chain")
        out.append(p)
    return out[::-1]


def optimal_lasso(g: sp.csr_matrix, initial: int, accepting: np.ndarray, stats: dict) -> tuple[list, list] | None:
    """Node ids of the cheapest lasso of the weighted graph ``g`` from ``initial`` through an ``accepting``
    node (prefix before it, non-empty cycle from it), or None when no accepting node reachable from
    ``initial`` lies on a cycle (steps 2-4 of the module docstring; sizes go into ``stats``)."""
    d0, pred0 = dijkstra(g, directed=True, indices=initial, return_predecessors=True)
    reach = np.isfinite(d0)
    stats["product_reachable_nodes"] = int(reach.sum())
    acc = np.flatnonzero(accepting & reach)
    ncomp, comp = connected_components(g, directed=True, connection="strong")
    sizes = np.bincount(comp, minlength=ncomp)
    ind, ptr, w = g.indices, g.indptr, g.data
    self_loop = np.array([a in ind[ptr[a]:ptr[a + 1]] for a in acc], dtype=bool)
    acc = acc[(sizes[comp[acc]] > 1) | self_loop]
    if len(acc) == 0:
        return None
    gt = g.T.tocsr()
    dA = dijkstra(gt, directed=True, indices=acc, min_only=True)
    # LB(a) = min over edges a -> y of chi(a, y) + d(y, A)
    lb = np.full(len(acc), np.inf)
    for k, a in enumerate(acc):
        lo, hi = ptr[a], ptr[a + 1]
        if hi > lo:
            lb[k] = float(np.min(w[lo:hi] + dA[ind[lo:hi]]))
    order = np.lexsort((acc, d0[acc] + lb))
    best, best_a, best_cycle = np.inf, -1, None
    cycles = 0
    tin_ptr, tin_ind, tin_w = gt.indptr, gt.indices, gt.data
    for k in order:
        a = int(acc[k])
        if d0[a] + lb[k] >= best:
            break
        limit = best - d0[a]
        dist, pred = dijkstra(g, directed=True, indices=a, return_predecessors=True, limit=limit)
        cycles += 1
        lo, hi = tin_ptr[a], tin_ptr[a + 1]
        preds = tin_ind[lo:hi]
        tot = dist[preds] + tin_w[lo:hi]
        if len(tot) == 0:
            continue
        i = int(np.argmin(tot))
        c = float(tot[i])
        if d0[a] + c < best:
            p = int(preds[i])
            best, best_a = float(d0[a] + c), a
            best_cycle = _path(pred, a, p) if p != a else [a]
    stats.update(accepting_candidates=int(len(acc)), cycle_searches=cycles)
    if best_a < 0:
        return None
    return _path(pred0, initial, best_a)[:-1], best_cycle
