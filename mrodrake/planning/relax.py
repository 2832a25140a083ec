"""Proofs of unsatisfiability on sound over-approximations of the executed words (no explicit product).

Executed words (:mod:`mrodrake.planning.semantics`) projected on AP_φ have a simple shape: every letter is
followed either by the same letter (a step without a visible crossing, or another entity's invisible
crossing) or by the letter with one bit flipped (one body leaving or entering a region the task mentions).
A *relaxation* keeps, for a set E of entities, each entity's own motion and forgets everything that couples
them or constrains the others:

* an entity is in a region or between two regions (leaving k for k', then entering k'); it travels only
  between regions connected for its radius (robots) or for the smallest covering radius a team strong
  enough to carry it can have, plus the docking slack of :meth:`~mrodrake.ts.TransitionSystem.travel_radius`,
  and only between regions where that team, of robots that can reach both, fits (objects:
  :meth:`~mrodrake.ts.TransitionSystem.carry_connections`; a larger radius only removes connections);
  objects no team can move (:func:`~mrodrake.planning.exact.immovable_objects`) and robots without a passage
  never move; an entity never enters a region the task keeps it out of on every accepted run, and a team
  that carries an object is of robots the task lets into both regions
  (:func:`~mrodrake.planning.confine.task_regions`);
* packing (P_s), step capacity, Λ and grasping are dropped: entities of E move independently, one visible
  crossing per letter, any number of invisible ones (ε, closed over); only a guard cube that needs two
  entities in one region where they never fit together (:meth:`Relaxations._crowded`) is never usable;
* entities outside E are unconstrained: an NBA cube is usable if E's part holds on the letter and the rest
  is satisfiable by *some* placement of the other entities (each in at most one region it can reach; one
  that can move may be in none, between regions).

Every executed word of the real TS is a word of the relaxation, so a relaxation whose product with the NBA
has no reachable accepting cycle proves the task unsatisfiable.  :func:`prove_unsat` tries E = ∅ (which
labels the TS can produce at all, with the confinement of each entity), each entity the task mentions on its
own, pairs of entities that share a guard cube, and all mentioned entities together, while the abstract
product stays below :data:`PRODUCT_LIMIT` nodes.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components

from mrodrake.logic.nba import NBA
from mrodrake.planning.confine import carry_connections, task_regions
from mrodrake.planning.exact import immovable_objects
from mrodrake.ts import TransitionSystem, reachable

#: Largest abstract product (abstract states × NBA states) a relaxation builds.
PRODUCT_LIMIT = 200_000
#: Largest abstract product graph (edges) a relaxation builds; a larger one is skipped (no proof).
EDGE_LIMIT = 4_000_000
#: At most this many entity pairs are tried.
MAX_PAIRS = 40
#: The relaxations tried together build at most this many abstract product states.
TOTAL_LIMIT = 2_000_000


@dataclass(frozen=True)
class Motion:
    """The abstract motion of one entity: states ``0..K-1`` are regions, the others ``(k, k')`` between
    two regions; ``region[x]`` is the region whose AP_φ bit holds in state x (−1: none); ``stay`` and
    ``move`` are sparse 0/1 matrices of one letter: invisible crossings only, or exactly one visible one."""

    entity: int
    initial: int
    region: np.ndarray
    stay: sp.csr_matrix
    move: sp.csr_matrix

    @property
    def n(self) -> int:
        return len(self.region)


def _closure(eps: sp.csr_matrix) -> sp.csr_matrix:
    """Reflexive-transitive closure of a 0/1 matrix."""
    n = eps.shape[0]
    C = (sp.identity(n, format="csr", dtype=np.int64) + eps).astype(bool).astype(np.int64)
    while True:
        C2 = (C @ C).astype(bool).astype(np.int64)
        if (C2 != C).nnz == 0:
            return C2.tocsr()
        C = C2


def entity_connections(ts: TransitionSystem, immovable, regions=None) -> list[np.ndarray]:
    """``C[e][k, k']``: can entity e ever travel from region k to k' (see the module docstring); ``regions``:
    where the task lets each entity be (:func:`~mrodrake.planning.confine.task_regions`)."""
    out = []
    K = ts.K
    for i in range(ts.N):
        C = ts.connections(ts.robot_radius[i]).copy()
        if regions is not None:
            out_of = [k for k in range(K) if k not in regions[i]]
            C[out_of, :] = False
            C[:, out_of] = False
        out.append(C)
    for j in range(ts.M):
        C = None if j in immovable else carry_connections(ts, j, regions)
        out.append(np.zeros((K, K), dtype=bool) if C is None else C.copy())
    for C in out:
        np.fill_diagonal(C, False)
    return out


def motion(ts: TransitionSystem, e: int, C: np.ndarray, relevant: int) -> Motion:
    """The :class:`Motion` of entity e with connections C (only what its initial region reaches)."""
    K = ts.K
    k0 = ts.initial[e]
    seen = reachable(C, k0)
    index = {("in", k): k for k in range(K)}
    pairs = [(k, k2) for k in sorted(seen) for k2 in sorted(seen) if k != k2 and C[k, k2]]
    for p in pairs:
        index[("go",) + p] = len(index)
    n = len(index)
    region = np.full(n, -1, dtype=np.int64)
    for k in range(K):
        if relevant >> (e * K + k) & 1:
            region[k] = k
    eps_r, eps_c, vis_r, vis_c = [], [], [], []
    for k, k2 in pairs:
        x = index[("go", k, k2)]
        for src, dst, bit in ((k, x, k), (x, k2, k2)):  # leave k, enter k2
            if relevant >> (e * K + bit) & 1:
                vis_r.append(src)
                vis_c.append(dst)
            else:
                eps_r.append(src)
                eps_c.append(dst)

    def mat(r, c, size):
        r, c = np.asarray(r, dtype=np.int64), np.asarray(c, dtype=np.int64)
        return sp.csr_matrix((np.ones(len(r), dtype=np.int64), (r, c)), shape=(size, size))

    eps_r, eps_c, vis_r, vis_c = (np.asarray(x, dtype=np.int64) for x in (eps_r, eps_c, vis_r, vis_c))

    # states joined by invisible crossings both ways read the same letters from then on: one state each
    _, comp = connected_components(mat(eps_r, eps_c, n), directed=True, connection="strong")
    m = int(comp.max()) + 1
    reg = np.full(m, -1, dtype=np.int64)
    reg[comp] = region
    E = _closure(mat(comp[eps_r], comp[eps_c], m))
    move = (E @ mat(comp[vis_r], comp[vis_c], m) @ E).astype(bool).astype(np.int64).tocsr()
    return Motion(e, int(comp[k0]), reg, E, move)


def accepting_lasso(g: sp.csr_matrix, initial: int, accepting: np.ndarray) -> bool:
    """Does a node reachable from ``initial`` with ``accepting[node]`` lie on a cycle of ``g``?"""
    order = breadth_first_order(g, initial, directed=True, return_predecessors=False)
    cand = order[accepting[order]]
    if len(cand) == 0:
        return False
    _, comp = connected_components(g, directed=True, connection="strong")
    sizes = np.bincount(comp)
    if np.any(sizes[comp[cand]] > 1):
        return True
    return bool(np.any(g[cand, cand]))


@dataclass
class Relaxations:
    """The relaxations of one TS and one NBA over ``ts.propositions`` (``relevant``: AP_φ)."""

    ts: TransitionSystem
    nba: NBA
    relevant: int
    stats: dict = field(default_factory=dict)

    def __post_init__(self):
        ts = self.ts
        K, n_ent = ts.K, ts.N + ts.M
        self.immovable = immovable_objects(ts)
        self.regions = task_regions(ts, self.nba)
        self.conn = entity_connections(ts, self.immovable, self.regions)
        self.reach = []
        for e in range(n_ent):
            self.reach.append(sum(1 << k for k in reachable(self.conn[e], ts.initial[e])))
        self.mentioned = [e for e in range(n_ent) if (self.relevant >> (e * K)) & ((1 << K) - 1)]
        self.names = ts.robot_names + ts.object_names
        self.cubes = [[(p, n, d) for g, d in row for p, n in g] for row in self.nba.edges]
        self._motions: dict[int, Motion] = {}
        self._tables()

    def motion(self, e: int) -> Motion:
        m = self._motions.get(e)
        if m is None:
            m = self._motions[e] = motion(self.ts, e, self.conn[e], self.relevant)
        return m

    # ------------------------------------------------------------------------------------ cubes
    def _tables(self) -> None:
        """Per guard cube: its edge (q, q'), and the entities that cannot satisfy their part of it alone."""
        ts, K = self.ts, self.ts.K
        full = (1 << K) - 1
        qs, ds, self.cpos, self.cneg, self.bad = [], [], [], [], []
        for q, row in enumerate(self.cubes):
            for p, n, d in row:
                qs.append(q)
                ds.append(d)
                self.cpos.append(p)
                self.cneg.append(n)
                bad = set()
                for e in range(ts.N + ts.M):
                    pe, ne = (p >> (e * K)) & full, (n >> (e * K)) & full
                    if pe & ne:
                        bad.add(-1)
                    elif pe:
                        if pe & (pe - 1) or not pe & self.reach[e]:
                            bad.add(e)
                    elif ne and self.reach[e] == 1 << ts.initial[e] and ne >> ts.initial[e] & 1:
                        bad.add(e)
                if self._crowded(p):
                    bad.add(-1)
                self.bad.append(frozenset(bad))
        Q = self.nba.num_states
        C = len(qs)
        self.edge_of = sp.csr_matrix((np.ones(C, dtype=np.int64), (np.arange(C), np.array(qs, dtype=np.int64) * Q
                                      + np.array(ds, dtype=np.int64))), shape=(C, Q * Q))
        self._compat: dict[int, np.ndarray] = {}

    def _crowded(self, p: int) -> bool:
        """Do two entities the cube puts in one region never fit there together?  Every letter's entities of
        region k are units of the source or target state of its step, which fit together (P_s, step capacity):
        a body of radius r has its centre within R_k − r of c_k, an object outside its initial region within
        R_k − b − spacing/2 (b: the smallest covering radius of a team that can carry it, which put it down or
        holds it), and two objects keep the spacing.  Of two objects in k, not both at home, the one that
        entered k last came with its team: at the end of that step its team's disk (radius >= b) and the other
        object fit in k."""
        ts, K, N = self.ts, self.ts.K, self.ts.N
        sp = ts.spacing
        for k in range(K):
            es = [e for e in range(N + ts.M) if p >> (e * K + k) & 1]
            if len(es) < 2:
                continue
            R = ts.region_radius[k]
            body, reach, team = [], [], []
            for e in es:
                r = ts.robot_radius[e] if e < N else ts.object_radius[e - N]
                b = ts.smallest_team_radius(e - N) if e >= N else None
                body.append(r)
                team.append(b)
                reach.append(R - r if b is None or k == ts.initial[e] else R - b - 0.5 * sp)
            for a, c in itertools.combinations(range(len(es)), 2):
                objects = es[a] >= N and es[c] >= N
                gap = sp if objects else 0.0
                if reach[a] + reach[c] < body[a] + body[c] + gap - 1e-9:
                    return True
                if not objects or (k == ts.initial[es[a]] and k == ts.initial[es[c]]):
                    continue
                # x entered k after y, with its team around it
                if not any(team[x] is not None and R - team[x] - 0.5 * sp + reach[y] >= team[x] + body[y] + sp - 1e-9
                           for x, y in ((a, c), (c, a))):
                    return True
        return False

    def compat(self, e: int) -> np.ndarray:
        """``A[c, r + 1]``: does entity e in region r (r = −1: in no region AP_φ names) satisfy e's part of
        cube c?"""
        A = self._compat.get(e)
        if A is None:
            K = self.ts.K
            full = (1 << K) - 1
            A = np.zeros((len(self.cpos), K + 1), dtype=bool)
            for c, (p, n) in enumerate(zip(self.cpos, self.cneg)):
                pe, ne = (p >> (e * K)) & full, (n >> (e * K)) & full
                A[c, 0] = pe == 0
                for k in range(K):
                    A[c, k + 1] = (pe & ~(1 << k)) == 0 and not ne >> k & 1
            self._compat[e] = A
        return A

    # ------------------------------------------------------------------------------------ one relaxation
    def size(self, entities) -> int:
        n = 1
        for e in entities:
            n *= self.motion(e).n
        return n * self.nba.num_states

    def accepts(self, entities) -> bool:
        """Does the relaxation keeping the motion of ``entities`` have an accepting lasso?  (True also when
        its product graph would exceed :data:`EDGE_LIMIT`: no proof.)"""
        Q = self.nba.num_states
        inside = frozenset(entities)
        nnz = [(self.motion(e).stay.nnz, self.motion(e).move.nnz) for e in entities]
        est = sum(int(np.prod([b if i == j else a for i, (a, b) in enumerate(nnz)])) for j in range(len(nnz)))
        if est + int(np.prod([a for a, _ in nnz])) > EDGE_LIMIT // 2:
            self.stats["relaxation_skipped"] = self.stats.get("relaxation_skipped", 0) + 1
            return True
        good = np.array([b <= inside for b in self.bad], dtype=bool)
        stay = sp.csr_matrix(np.ones((1, 1), dtype=np.int64))
        move = sp.csr_matrix((1, 1), dtype=np.int64)
        letter = np.zeros(1, dtype=np.int64)  # mixed-radix code of the per-entity letters (region + 1)
        init = 0
        for e in entities:
            m = self.motion(e)
            # joint letter: every entity closes over invisible crossings, at most one crosses visibly
            stay, move = (sp.kron(stay, m.stay, format="csr"),
                          sp.kron(move, m.stay, format="csr") + sp.kron(stay, m.move, format="csr"))
            letter = (letter[:, None] * (self.ts.K + 1) + (m.region + 1)[None, :]).ravel()
            init = init * m.n + m.initial
        codes, lid = np.unique(letter, return_inverse=True)
        lid = lid.ravel()
        if len(codes) * len(good) > 20_000_000:
            self.stats["relaxation_skipped"] = self.stats.get("relaxation_skipped", 0) + 1
            return True
        usable = np.tile(good, (len(codes), 1))
        rest = codes.copy()
        for e in reversed(list(entities)):
            rest, r = np.divmod(rest, self.ts.K + 1)
            usable &= self.compat(e)[:, r].T
        M = (sp.csr_matrix(usable.astype(np.int64)) @ self.edge_of).toarray() > 0  # (letters, Q*Q)
        A = (stay + move).tocoo()
        per_row = M.sum(axis=1)[lid[A.row]]
        if int(per_row.sum()) > EDGE_LIMIT:
            self.stats["relaxation_skipped"] = self.stats.get("relaxation_skipped", 0) + 1
            return True
        rows_all, cols_all = [], []
        order = np.argsort(lid[A.row], kind="stable")
        r_sorted, c_sorted = A.row[order].astype(np.int64), A.col[order].astype(np.int64)
        bounds = np.searchsorted(lid[r_sorted], np.arange(len(codes) + 1))
        for l in range(len(codes)):
            lo, hi = bounds[l], bounds[l + 1]
            qq = np.flatnonzero(M[l])
            if hi == lo or len(qq) == 0:
                continue
            qs, q2s = np.divmod(qq, Q)
            rows_all.append((r_sorted[lo:hi, None] * Q + qs[None, :]).ravel())
            cols_all.append((c_sorted[lo:hi, None] * Q + q2s[None, :]).ravel())
        if not rows_all:
            return False
        rows, cols = np.concatenate(rows_all), np.concatenate(cols_all)
        n = A.shape[0] * Q
        graph = sp.csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n, n))
        acc = np.zeros(Q, dtype=bool)
        acc[list(self.nba.accepting)] = True
        return accepting_lasso(graph, init * Q + self.nba.initial, np.tile(acc, A.shape[0]))

    # ------------------------------------------------------------------------------------ proof search
    def candidates(self) -> list[tuple[str, tuple[int, ...]]]:
        """(kind, entities) in the order :meth:`prove` tries them."""
        out: list[tuple[str, tuple[int, ...]]] = [("labels", ())]
        out += [("entity", (e,)) for e in self.mentioned]
        K = self.ts.K
        full = (1 << K) - 1
        pairs = set()
        for row in self.cubes:
            for p, n, _ in row:
                es = [e for e in self.mentioned if ((p | n) >> (e * K)) & full]
                pairs.update(itertools.combinations(es, 2))
        out += [("pair", pr) for pr in sorted(pairs)[:MAX_PAIRS]]
        if len(self.mentioned) > 2:
            out.append(("joint", tuple(self.mentioned)))
        return out

    def prove(self) -> str | None:
        """A one-line "task is unsatisfiable: ..." when some relaxation has no accepting lasso, else None
        (the relaxations of :meth:`candidates` in order, within :data:`PRODUCT_LIMIT` each and
        :data:`TOTAL_LIMIT` together)."""
        t0 = time.perf_counter()
        tried, work = 0, 0
        for kind, es in self.candidates():
            size = self.size(es)
            if size > PRODUCT_LIMIT or work + size > TOTAL_LIMIT:
                continue
            tried += 1
            work += size
            if not self.accepts(es):
                self.stats.update(relaxations_tried=tried, relaxation=kind,
                                  relaxation_seconds=time.perf_counter() - t0)
                return self._message(kind, es, size)
        self.stats.update(relaxations_tried=tried, relaxation=None, relaxation_seconds=time.perf_counter() - t0)
        return None

    def _message(self, kind: str, es: tuple[int, ...], size: int) -> str:
        Q = self.nba.num_states
        who = ", ".join(self._who(e) for e in es)
        if kind == "labels":
            return (f"task is unsatisfiable: no accepting cycle of the NBA ({Q} states) has guards that executed "
                    "words of the TS can satisfy (relaxation: each entity confined to the regions it can reach"
                    f"{' and the task lets it into' if self.regions is not None else ''}, between regions while "
                    "it travels; entities a guard needs in one region fit there together)")
        if kind == "entity":
            return (f"task is unsatisfiable: {who} cannot produce a word the NBA accepts even with every other "
                    f"entity unconstrained (relaxation: its own travels only, packing and Λ dropped; {size} "
                    "abstract product states searched)")
        return (f"task is unsatisfiable: {who} moving independently cannot produce a word the NBA accepts "
                f"(relaxation: one crossing at a time, packing, Λ and grasps dropped, other entities "
                f"unconstrained; {size} abstract product states searched)")

    def _who(self, e: int) -> str:
        return ("robot " if e < self.ts.N else "object ") + self.names[e]
