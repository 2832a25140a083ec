"""The executed word of sequential execution, shared by the planners, ``Plan.verify`` and the execution monitor.

The paper's product (Sec. III-B) lets the NBA read one letter per TS step, the label L(s) of the step's source
state, as if all actions of the step happened at once.  Executed one entity at a time (Sec. III-A, sequential
execution), a step passes through labels that the plan never lists.  We define the word that execution
produces, and plan on it:

* within a TS step s → s' the releases and grasps run first (they change no label); then the region-changing
  actions (navigations, transports) run one at a time in an *order* π chosen by the executor (stored in the
  plan);
* during an action each of its bodies (the robot; or the object and every team member) leaves its source
  region once and enters its destination once (its ball crosses each rim once), in whatever interleaving the
  geometry gives;
* the NBA reads letters projected onto the task's propositions AP_φ (the atoms of the formula): at every body
  crossing that changes the projected label it reads the label being left; a step without such a crossing
  reads its source label once (the paper's reading).  The first letter of a step is therefore always the
  projection of L(s), and L(s') is read by the next step.

A product edge (s, q) → (s', q') exists iff s → s' is a TS transition and there is an order π such that for
**every** crossing interleaving the NBA can go from q to q' reading the step's letters
(:meth:`ExecutedWords.successors`).
The planned NBA states are then states of the executed run whatever the geometry does, and a monitor that
reads the executed word in the same way checks the plan soundly.  The computation runs on families of
NBA-state subsets over the lattice of each action's crossings (a downset lattice of at most 3^bodies nodes)
and a search over the orders of the actions whose crossings AP_φ can see (memoised on the set of actions left
and the family); actions whose bodies AP_φ never mentions produce no letter and can run in any order.

:func:`plan_word_graph` and :func:`check_plan_words` model-check a plan independently of the NBA run the
planner found: every word any execution of the lasso may produce (all crossing interleavings, every suffix
cycle) must satisfy the formula, i.e. the word graph times an NBA of ¬φ has no accepting cycle.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator, Sequence
from typing import NamedTuple

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from mrodrake.geometry import grasp_layout
from mrodrake.logic.formula import Formula, Not, atoms
from mrodrake.logic.nba import NBA
from mrodrake.logic.translate import translate
from mrodrake.ts import Action, Navigate, State, TransitionSystem, Transport


def relevant_mask(ts: TransitionSystem, formula: Formula) -> int:
    """Bit mask of AP_φ: the TS propositions that occur in the formula."""
    names = atoms(formula)
    return sum(1 << b for b, p in enumerate(ts.propositions) if p in names)


def bodies(ts: TransitionSystem, a: Action) -> tuple[int, ...]:
    """Entities moved by a region-changing action (robots 0..N−1, objects N..N+M−1): the robot of a
    navigation; the object, then the team, of a transport."""
    if isinstance(a, Navigate):
        return (a.robot,)
    return (ts.N + a.obj,) + tuple(a.team)


def region_changing(actions: Sequence[Action]) -> list[Action]:
    return [a for a in actions if isinstance(a, (Navigate, Transport))]


class Crossing(NamedTuple):
    """One body of a region-changing action: the AP_φ bit its leaving clears and the bit its entering sets
    (−1 where AP_φ does not mention the source / destination proposition), and the bodies of the same
    action that must have left the source before this one can enter the destination (:func:`entry_order`)."""

    body: int
    leave: int
    enter: int
    after: tuple[int, ...] = ()


#: Slack (m) on how far a grasping robot's centre may sit from its layout slot (docking tolerance, rounding).
TEAM_SLACK = 0.1


def entry_order(ts: TransitionSystem, a: Action) -> dict[int, tuple[int, ...]]:
    """body f -> the bodies e of the same transport that leave ``a.src`` before f enters ``a.dst``.

    The geometry that decides interleavings: a body's ball lies in region k iff its centre is within
    R_k − r of c_k (:func:`~mrodrake.execution.monitor.entity_regions`), and a team is rigid while it
    travels, each member's centre within ρ = d + :data:`TEAM_SLACK` of the object's (d: the grasp layout's
    slot distance, :func:`~mrodrake.geometry.grasp_layout`; ρ = 0 for the object).  Body e still in the
    source and body f already in the destination put the two region centres at most
    (R_src − r_e + ρ_e) + (R_dst − r_f + ρ_f) apart; farther apart, f enters only after e has left.  Every
    crossing order this removes is one that no execution produces, so the words kept still contain every
    executed word.  A navigation moves one body (leaving before entering): nothing to order."""
    if not isinstance(a, Transport):
        return {}
    layout = grasp_layout(ts.object_radius[a.obj], [ts.robot_radius[i] for i in a.team], ts.grasp_gap)
    reach = {ts.N + a.obj: (ts.object_radius[a.obj], 0.0)}
    for i in a.team:
        reach[i] = (ts.robot_radius[i], layout.distance + TEAM_SLACK)
    gap = float(ts.dist[a.src, a.dst])
    R0, R1 = ts.region_radius[a.src], ts.region_radius[a.dst]
    out = {}
    for f, (rf, pf) in reach.items():
        before = tuple(e for e, (re, pe) in reach.items()
                       if e != f and gap > (R0 - re + pe) + (R1 - rf + pf))
        if before:
            out[f] = before
    return out


def crossings(ts: TransitionSystem, relevant: int, a: Action) -> tuple[Crossing, ...]:
    """The crossings of action ``a`` that AP_φ can see, with the entry order the geometry imposes."""
    K = ts.K
    out = []
    order = entry_order(ts, a)
    for b in bodies(ts, a):
        lb, eb = b * K + a.src, b * K + a.dst
        c = Crossing(b, lb if relevant >> lb & 1 else -1, eb if relevant >> eb & 1 else -1)
        if c.leave >= 0 or c.enter >= 0:
            out.append(c)
    visible_leave = {c.body for c in out if c.leave >= 0}
    return tuple(Crossing(c.body, c.leave, c.enter,
                          tuple(e for e in order.get(c.body, ()) if e in visible_leave) if c.enter >= 0 else ())
                 for c in out)


def _events(cross: Sequence[Crossing]) -> tuple[list[tuple[int, int]], list[int]]:
    """Crossing events (bit, +1 set / −1 clear) and, per event, the mask of events that must precede it
    (a body leaves before it enters; an entry waits for the leaves of its ``after`` bodies)."""
    events, pre, leave_of = [], [], {}
    for c in cross:
        if c.leave >= 0:
            leave_of[c.body] = len(events)
            events.append((c.leave, -1))
            pre.append(0)
    for c in cross:
        if c.enter >= 0:
            events.append((c.enter, +1))
            need = 0
            for e in (c.body, *c.after):
                if e in leave_of:
                    need |= 1 << leave_of[e]
            pre.append(need)
    return events, pre


@functools.cache
def _prefixes(n: int) -> int:
    """Order prefixes of n actions, the empty one included: Σ_k n!/(n−k)! (cached)."""
    return sum(math.perm(n, k) for k in range(n + 1))


def _apply(mask: int, event: tuple[int, int]) -> int:
    bit, sign = event
    return mask | (1 << bit) if sign > 0 else mask & ~(1 << bit)


def _spread(fam: dict, succ, images: set) -> None:
    """Add ``images`` to the family of every node in ``succ`` (a node's first family is a copy)."""
    for D2 in succ:
        got = fam.get(D2)
        if got is None:
            fam[D2] = set(images)
        else:
            got.update(images)


def _push_orders(stack: list, known: dict, after, ids, F, m: int, left: int, prefix: tuple) -> None:
    """Push onto ``stack`` every extension of a partial order by one action still ``left`` (bit i: action i)
    whose run (``after``, memoised in ``known``) has not died, the last action first so the first pops first."""
    for i in range(len(ids) - 1, -1, -1):
        if left >> i & 1:
            hit = known.get((F, m, ids[i]))
            F2, m2 = after(F, m, ids[i]) if hit is None else hit
            if 0 not in F2:
                stack.append((F2, m2, left & ~(1 << i), prefix + (i,)))


def _record_common(F: frozenset, prefix: tuple[int, ...], out: dict[int, tuple[int, ...]]) -> None:
    """Record ``prefix`` (an order) for every NBA state that every member of the family F reaches."""
    common = -1
    for S in F:
        common &= S
    d = 0
    while common > 0:
        if common & 1:
            out.setdefault(d, prefix)
        common >>= 1
        d += 1


def interleavings(cross: Sequence[Crossing]) -> Iterator[list[tuple[int, int]]]:
    """Every order of the crossing events of one action (each body leaves before it enters)."""
    events, pre = _events(cross)
    n = len(events)

    def rec(done: int, seq: list) -> Iterator[list]:
        if done == (1 << n) - 1:
            yield list(seq)
            return
        for i in range(n):
            if not done >> i & 1 and done & pre[i] == pre[i]:
                seq.append(events[i])
                yield from rec(done | 1 << i, seq)
                seq.pop()

    yield from rec(0, [])


def _mentioned(nba: NBA, q: int) -> int:
    """The propositions the guards of q's edges mention (δ(q, ·) depends on no other bit of a letter)."""
    used = 0
    for guard, _ in nba.edges[q]:
        for p, n in guard:
            used |= p | n
    return used


class GuardTable:
    """NBA successors of letters, for states whose guards have many cubes: the cubes are bits of Python
    integers, and per group of up to eight of the propositions they mention a table (filled on first use)
    maps the group's bits of a letter to the cubes those bits falsify, so a letter costs one lookup per group
    (same answers as :meth:`~mrodrake.logic.nba.NBA.successors`, which loops over the cubes)."""

    #: States with more cubes than this use the table.
    min_cubes = 16
    #: Propositions per group.
    group_bits = 8

    def __init__(self, nba: NBA):
        self.nba = nba
        self._tables: dict[int, tuple | None] = {}
        self._joint: tuple | None = None

    def _table(self, q: int):
        """(groups, all cubes, (destination, its cubes)...) of state q, or None for few cubes.  A group is
        (bits of the letter it reads, (bit, cubes needing it, cubes forbidding it)..., memo)."""
        if q in self._tables:
            return self._tables[q]
        flat = [(p, n, d) for g, d in self.nba.edges[q] for p, n in g]
        table = None
        if len(flat) > self.min_cubes:
            to: dict[int, int] = {}
            for c, (_, _, d) in enumerate(flat):
                to[d] = to.get(d, 0) | 1 << c
            table = (self._groups([(p, n) for p, n, _ in flat], self.group_bits), (1 << len(flat)) - 1,
                     tuple(to.items()))
        self._tables[q] = table
        return table

    @staticmethod
    def _groups(flat: list[tuple[int, int]], k: int) -> tuple:
        """The groups of a table over the cubes ``flat`` (pos, neg), cube c as bit c."""
        used = 0
        for p, n in flat:
            used |= p | n
        bits = [b for b in range(used.bit_length()) if used >> b & 1]
        need = dict.fromkeys(bits, 0)
        forbid = dict.fromkeys(bits, 0)
        for c, (p, n) in enumerate(flat):
            for b in bits:
                if p >> b & 1:
                    need[b] |= 1 << c
                if n >> b & 1:
                    forbid[b] |= 1 << c
        return tuple((sum(1 << b for b in bits[i:i + k]), tuple((b, need[b], forbid[b]) for b in bits[i:i + k]), {})
                     for i in range(0, len(bits), k))

    @staticmethod
    def _holding(groups: tuple, alive: int, letter: int) -> int:
        """The cubes of ``alive`` that ``letter`` satisfies."""
        for gmask, gbits, memo in groups:
            v = letter & gmask
            f = memo.get(v)
            if f is None:
                f = 0
                for b, nd, fb in gbits:
                    f |= fb if v >> b & 1 else nd
                memo[v] = f
            alive &= ~f
            if not alive:
                break
        return alive

    def columns(self, letter: int) -> tuple[tuple[int, int], ...]:
        """(q, δ(q, letter) as a mask) for every state q with successors: one table over the cubes of all
        states, so a letter costs one lookup per group for the whole NBA."""
        if self._joint is None:
            flat, edges = [], []
            for q, row in enumerate(self.nba.edges):
                for g, d in row:
                    cubes = 0
                    for p, n in g:
                        cubes |= 1 << len(flat)
                        flat.append((p, n))
                    edges.append((q, d, cubes))
            self._joint = (self._groups(flat, self.group_bits), (1 << len(flat)) - 1, tuple(edges))
        groups, alive, edges = self._joint
        alive = self._holding(groups, alive, letter)
        out: dict[int, int] = {}
        if alive:
            for q, d, cubes in edges:
                if alive & cubes:
                    out[q] = out.get(q, 0) | 1 << d
        return tuple(out.items())

    def successors_mask(self, q: int, letter: int) -> int:
        """Bit mask of δ(q, letter)."""
        table = self._table(q)
        if table is None:
            return sum(1 << d for d in self.nba.successors(q, letter))
        groups, alive, to = table
        alive = self._holding(groups, alive, letter)
        out = 0
        for d, cubes in to:
            if alive & cubes:
                out |= 1 << d
        return out


class ExecutedWords:
    """The executed-word semantics (module docstring) of a TS and an NBA over ``ts.propositions``;
    ``relevant`` is the AP_φ mask (:func:`relevant_mask`).  All queries are cached; every answer is a pure
    function of the step (never of earlier queries)."""

    #: Complete orders of a step's visible actions tried per query (4! = 24: every order up to four).
    max_orders = 24
    #: Order prefixes explored per query (4 visible actions have 65).
    max_nodes = 256
    #: NBAs with at most this many states search the orders of a step for all start states at once.
    max_joint = 16

    def __init__(self, ts: TransitionSystem, nba: NBA, relevant: int):
        if tuple(nba.ap) != tuple(ts.propositions):
            raise ValueError("the NBA must be over the TS propositions (use nba.with_ap(ts.propositions))")
        self.ts, self.nba, self.relevant = ts, nba, int(relevant)
        self.Q = nba.num_states
        K = ts.K
        n_ent = ts.N + ts.M
        self.entity_region = np.array([[bool(self.relevant >> (e * K + k) & 1) for k in range(K)]
                                       for e in range(n_ent)], dtype=bool).reshape(n_ent, K)
        self._entities = np.arange(n_ent)
        self.guards = GuardTable(nba)
        self._succ_bits: dict[tuple[int, int], int] = {}  # (q, letter & used[q]) -> δ(q, letter) mask
        self._used = [_mentioned(nba, q) for q in range(self.Q)]
        self._delta: dict[tuple[int, int], int] = {}
        self._lattice: dict[tuple, tuple[frozenset, int]] = {}
        self._cross_ids: dict[tuple, int] = {}
        self._lattices: list[list[tuple[int, int, int, tuple[int, ...]]]] = []
        self._crosses: list[tuple[Crossing, ...]] = []  # cross id -> crossings
        self._chains: list[tuple[tuple[int, int], ...] | None] = []  # lattices with one interleaving: letters
        self._step_ids: dict[tuple[int, tuple], int] = {}  # (mask, signature) -> step id
        self._step_keys: list[tuple[int, tuple]] = []  # step id -> (mask, signature)
        self._step_cids: list[tuple[int, ...]] = []  # step id -> cross ids of the signature
        self._step_orders: list[list[dict[int, tuple[int, ...]] | None]] = []  # step id -> per q: q' -> order
        self._row_at = np.full(64 * self.Q, -1, dtype=np.int64)  # sid·Q + q -> row of _row_store (-1: not yet)
        self._row_store = np.zeros((64, self.Q), dtype=bool)
        self._num_rows = 0
        self._full: dict[int, np.ndarray] = {}
        self._pair_steps: dict[tuple[State, State], int] = {}
        self._label_matrix: dict[int, np.ndarray] = {}
        self._some: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self._cross: dict[Action, tuple[Crossing, ...]] = {}
        self._keys: dict[tuple[State, State], tuple[int, tuple, tuple[Action, ...]]] = {}
        self._sigs: dict[tuple[State, State], tuple[int, tuple]] = {}
        self._move_cross: dict[tuple, tuple[Crossing, ...]] = {}
        self._move_ids: dict[tuple, int] = {}
        self._acc = sum(1 << f for f in nba.accepting)
        self._col = sum(1 << (self.Q * q) for q in range(self.Q))  # bit 0 of every row of a relation
        self._identity = sum(1 << (self.Q * q + q) for q in range(self.Q))
        self._columns: dict[int, tuple[tuple[int, ...], tuple[int, ...]]] = {}
        self._reads: dict[tuple[int, int], int] = {}
        self._joint: dict[tuple, tuple[tuple[int, ...], int]] = {}

    # ------------------------------------------------------------------------------------ NBA on subsets
    def delta(self, S: int, letter: int) -> int:
        """δ of a set of NBA states (bit mask) reading ``letter`` (a mask over the TS propositions)."""
        key = (S, letter)
        out = self._delta.get(key)
        if out is None:
            succ, used = self._succ_bits, self._used
            out, q, m = 0, 0, S
            while m:
                if m & 1:
                    k = (q, letter & used[q])
                    b = succ.get(k)
                    if b is None:
                        b = succ[k] = self.guards.successors_mask(q, letter)
                    out |= b
                m >>= 1
                q += 1
            self._delta[key] = out
        return out

    # ------------------------------------------------------------------------------------ one step
    def crossings(self, a: Action) -> tuple[Crossing, ...]:
        """:func:`crossings` of action ``a`` for this AP_φ (cached)."""
        c = self._cross.get(a)
        if c is None:
            c = self._cross[a] = crossings(self.ts, self.relevant, a)
        return c

    def key(self, s: State, t: State, actions: Sequence[Action] | None = None) -> tuple[int, tuple, list[Action]]:
        """(projected source label, crossing signature of the visible actions, those actions) of s → t."""
        if actions is None:
            hit = self._keys.get((s, t))
            if hit is not None:
                return hit[0], hit[1], list(hit[2])
        acts = region_changing(self.ts.actions(s, t) if actions is None else actions)
        cross = self.crossings
        vis = [(a, c) for a in acts if (c := cross(a))]
        out = self.ts.label_mask(s) & self.relevant, tuple(c for _, c in vis), [a for a, _ in vis]
        if actions is None:
            self._keys[(s, t)] = (out[0], out[1], tuple(out[2]))
        return out

    def signature(self, s: State, t: State) -> tuple[int, tuple]:
        """The first two of :meth:`key` (cached), read off the two states without building the actions
        (their order as in :meth:`~mrodrake.ts.TransitionSystem.actions`: transports, then navigations)."""
        hit = self._sigs.get((s, t))
        if hit is not None:
            return hit
        sig = []
        for m in self._moves(s, t):
            c = self._move_crossings(m)
            if c:
                sig.append(c)
        out = self._sigs[(s, t)] = (self.ts.label_mask(s) & self.relevant, tuple(sig))
        return out

    def _moves(self, s: State, t: State) -> list[tuple]:
        """The region-changing actions of s → t as plain tuples, in the order of
        :meth:`~mrodrake.ts.TransitionSystem.actions` (transports, then navigations)."""
        N, M = self.ts.N, self.ts.M
        moves = []
        for j in range(M):
            if s[N + j] != t[N + j]:
                team = tuple(i for i in range(N) if s[N + M + i] == j)
                moves.append(("T", j, team, s[N + j], t[N + j]))
        for i in range(N):
            if s[N + M + i] < 0 and t[N + M + i] < 0 and s[i] != t[i]:
                moves.append(("N", i, s[i], t[i]))
        return moves

    def _move_crossings(self, m: tuple) -> tuple[Crossing, ...]:
        """:meth:`crossings` of a move of :meth:`_moves` (cached)."""
        c = self._move_cross.get(m)
        if c is None:
            a = Transport(m[1], m[2], m[3], m[4]) if m[0] == "T" else Navigate(m[1], m[2], m[3])
            c = self._move_cross[m] = self.crossings(a)
        return c

    def _move_id(self, m: tuple) -> int:
        """:meth:`_cross_id` of a move's crossings, −1 when AP_φ sees none of them (cached)."""
        x = self._move_ids.get(m)
        if x is None:
            c = self._move_crossings(m)
            x = self._move_ids[m] = self._cross_id(c) if c else -1
        return x

    def _cross_id(self, cross: tuple) -> int:
        """A small integer naming one action's crossings, with its lattice precomputed: per reachable downset D
        of crossing events (in increasing order) the bits its events clear and set and the downsets one event
        larger (event bits are distinct, so the label after D does not depend on the events' order)."""
        cid = self._cross_ids.get(cross)
        if cid is None:
            events, pre = _events(cross)
            n = len(events)
            nodes, seen = [], {0: (0, 0)}  # reachable downset -> (bits its events clear, bits they set)
            for D in range(1 << n):  # a downset is reached from smaller ones only
                hit = seen.get(D)
                if hit is None:
                    continue
                clear, put = hit
                succ = []
                for i in range(n):
                    if not D >> i & 1 and D & pre[i] == pre[i]:
                        D2 = D | 1 << i
                        succ.append(D2)
                        if D2 not in seen:
                            b, sign = events[i]
                            seen[D2] = (clear | 1 << b, put) if sign < 0 else (clear, put | 1 << b)
                nodes.append((D, ~clear, put, tuple(succ)))
            cid = self._cross_ids[cross] = len(self._lattices)
            self._lattices.append(nodes)
            self._crosses.append(cross)
            chain = all(len(succ) <= 1 for *_, succ in nodes)
            self._chains.append(tuple((keep, put) for _, keep, put, _ in nodes) if chain else None)
        return cid

    def concurrent_reach(self, q: int, s: State, groups: Sequence[Sequence[Action]]) -> frozenset:
        """The subsets of NBA states reachable from q over a step from s whose visible actions run as
        ``groups`` one after another, the crossings of all bodies of one group in any interleaving (each
        action's own entry order kept): one subset per interleaving (the empty one if a word leaves the
        task)."""
        F, mask = frozenset([1 << q]), self.ts.label_mask(s) & self.relevant
        if not any(self.crossings(a) for g in groups for a in g):
            return frozenset([self.delta(1 << q, mask)])
        for g in groups:
            cross = tuple(c for a in g for c in self.crossings(a))
            if cross:
                F, mask = self._after_action(F, mask, cross)
        return F

    def _after_action(self, F: frozenset, mask: int, cross: tuple) -> tuple[frozenset, int]:
        """The family of subsets after one action's crossings, over all their interleavings, and the mask."""
        return self._after(F, mask, self._cross_id(cross))

    def _after(self, F: frozenset, mask: int, cid: int) -> tuple[frozenset, int]:
        key = (F, mask, cid)
        hit = self._lattice.get(key)
        if hit is not None:
            return hit
        delta, known = self.delta, self._delta
        chain = self._chains[cid]
        if chain is not None:  # one interleaving: each member reads the same letters
            letters = [mask & keep | put for keep, put in chain]
            last = letters.pop()
            images = set()
            for S in F:
                for letter in letters:
                    x = known.get((S, letter))
                    S = delta(S, letter) if x is None else x
                images.add(S)
            out = (frozenset(images), last)
            self._lattice[key] = out
            return out
        fam: dict[int, set] = {0: F}
        for D, keep, put, succ in self._lattices[cid]:
            letter = mask & keep | put
            if not succ:  # the full downset, last in the lattice: nothing read there
                break
            images = set()
            for S in fam[D]:
                x = known.get((S, letter))
                images.add(delta(S, letter) if x is None else x)
            _spread(fam, succ, images)
        out = (frozenset(fam[D]), letter)
        self._lattice[key] = out
        return out

    def _search(self, q: int, mask: int, sig: tuple, ids: Sequence[int] | None = None) -> dict[int, tuple[int, ...]]:
        """q' -> the first order of the visible actions (lexicographic over their canonical indices,
        canonical order first) that reaches q' from q for every interleaving.  At most :attr:`max_orders`
        complete orders are tried (all of them up to four visible actions) and at most :attr:`max_nodes`
        prefixes, so the result is a pure function of the step; an edge only another order would give is not
        used (sound, possibly incomplete); ``ids``: the cross ids of ``sig`` when known."""
        out: dict[int, tuple[int, ...]] = {}
        n = len(sig)
        after, known = self._after, self._lattice
        ids = [self._cross_id(c) for c in sig] if ids is None else ids
        if math.factorial(n) <= self.max_orders and _prefixes(n) <= self.max_nodes:
            # the budget cannot run out: depth first over the orders, lexicographic
            chains = [self._chains[c] for c in ids]
            if None not in chains:
                return self._search_chains(q, mask, chains)
            stack = [(frozenset([1 << q]), mask, (1 << n) - 1, ())]
            while stack:
                F, m, left, prefix = stack.pop()
                if left == 0:
                    _record_common(F, prefix, out)
                    continue
                _push_orders(stack, known, after, ids, F, m, left, prefix)
            return out
        budget = [self.max_orders, self.max_nodes]

        def rec(F: frozenset, m: int, left: int, prefix: tuple[int, ...]) -> None:
            if budget[0] <= 0 or budget[1] <= 0:
                return
            budget[1] -= 1
            if left == 0:
                budget[0] -= 1
                _record_common(F, prefix, out)
                return
            for i in range(n):
                if left >> i & 1:
                    hit = known.get((F, m, ids[i]))
                    F2, m2 = after(F, m, ids[i]) if hit is None else hit
                    if 0 not in F2:
                        rec(F2, m2, left & ~(1 << i), prefix + (i,))

        rec(frozenset([1 << q]), mask, (1 << n) - 1, ())
        return out

    def _step_id(self, mask: int, sig: tuple) -> int:
        """A small integer naming the step key (mask, signature), with its tables of orders and rows."""
        return self._code_id(mask, tuple(self._cross_id(c) for c in sig))

    def _code_id(self, mask: int, cids: tuple[int, ...]) -> int:
        """:meth:`_step_id` of the signature named by its cross ids."""
        key = (mask, cids)
        sid = self._step_ids.get(key)
        if sid is None:
            sid = self._step_ids[key] = len(self._step_keys)
            self._step_keys.append((mask, tuple(self._crosses[c] for c in cids)))
            self._step_cids.append(cids)
            self._step_orders.append([None] * self.Q)
            if (sid + 1) * self.Q > len(self._row_at):
                self._row_at = np.concatenate([self._row_at, np.full_like(self._row_at, -1)])
        return sid

    def step_id(self, s: State, t: State) -> int:
        """A small integer naming the step s → t for :meth:`step_rows` (s → t assumed a TS transition; steps
        with the same projected source label and crossing signature share it; cached on the pair)."""
        sid = self._pair_steps.get((s, t))
        if sid is None:
            move_id = self._move_id
            cids = tuple(x for x in map(move_id, self._moves(s, t)) if x >= 0)
            sid = self._pair_steps[(s, t)] = self._code_id(self.ts.label_mask(s) & self.relevant, cids)
        return sid

    def _orders(self, q: int, sid: int) -> dict[int, tuple[int, ...]]:
        """q' -> order of the visible actions for the step ``sid`` from q (cached)."""
        rows = self._step_orders[sid]
        r = rows[q]
        if r is None:
            mask, sig = self._step_keys[sid]
            if not sig:
                S = self.delta(1 << q, mask)
                r = {d: () for d in range(self.Q) if S >> d & 1}
            elif self.Q <= self.max_joint and self._unbudgeted(len(sig)):
                rows[:] = self._search_all(mask, sig, self._step_cids[sid])
                return rows[q]
            else:
                r = self._search(q, mask, sig, self._step_cids[sid])
            rows[q] = r
        return r

    def _unbudgeted(self, n: int) -> bool:
        """Can the search over the orders of n visible actions try them all (no budget can run out)?"""
        return math.factorial(n) <= self.max_orders and _prefixes(n) <= self.max_nodes

    # relations: a Q × Q boolean matrix as one integer, row q (the NBA states reached from q) in bits Q·q..Q·q+Q−1
    def _letter_columns(self, letter: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """The NBA states j with successors and δ(j, letter) of each as a mask, as two tuples (cached)."""
        cols = self._columns.get(letter)
        if cols is None:
            pairs = self.guards.columns(letter)
            cols = self._columns[letter] = tuple(zip(*pairs)) if pairs else ((), ())
        return cols

    def _read(self, R: int, letter: int) -> int:
        """The relation R followed by reading ``letter``: column j of R spread onto the row δ(j, letter)
        (cached)."""
        key = (R, letter)
        out = self._reads.get(key)
        if out is None:
            out, col = 0, self._col
            for j, m in zip(*self._letter_columns(letter)):
                c = R >> j & col
                if c:
                    out |= c * m
            self._reads[key] = out
        return out

    def _after_all(self, F: tuple[int, ...], mask: int, cid: int) -> tuple[tuple[int, ...], int]:
        """:meth:`_after` for all start states at once: F is a family of relations (one per interleaving so
        far, a sorted tuple).  A start state that some interleaving takes to the empty set is dropped from every
        member."""
        key = (F, mask, cid)
        hit = self._joint.get(key)
        if hit is not None:
            return hit
        read = self._read
        chain = self._chains[cid]
        if chain is not None:
            letters = [mask & keep | put for keep, put in chain]
            last = letters.pop()
            images = set()
            for R in F:
                for letter in letters:
                    R = read(R, letter)
                images.add(R)
        else:
            fam: dict[int, set] = {0: set(F)}
            for D, keep, put, succ in self._lattices[cid]:
                last = mask & keep | put
                if not succ:
                    break
                images = {read(R, last) for R in fam[D]}
                _spread(fam, succ, images)
            images = fam[D]
        if len(images) > 1:
            col, Q = self._col, self.Q
            alive = -1
            for R in images:
                nz = 0
                for j in range(Q):
                    nz |= R >> j & col
                alive &= nz
            keep_rows = alive * ((1 << Q) - 1)
            images = {R & keep_rows for R in images}
        out = (tuple(sorted(images)), last)
        self._joint[key] = out
        return out

    def _search_all(self, mask: int, sig: tuple, ids: Sequence[int] | None = None) -> list[dict[int, tuple[int, ...]]]:
        """:meth:`_search` for every start state q at once (unbudgeted searches): the same orders are tried in
        the same sequence on relations instead of subsets, so every row is the one :meth:`_search` gives."""
        Q, n = self.Q, len(sig)
        out: list[dict[int, tuple[int, ...]]] = [{} for _ in range(Q)]
        ids = [self._cross_id(c) for c in sig] if ids is None else ids
        if n == 1 and self._chains[ids[0]] is not None:  # one action, one interleaving: one word
            R = self._identity
            for keep, put in self._chains[ids[0]][:-1]:
                R = self._read(R, mask & keep | put)
            while R:
                low = R & -R
                q, d = divmod(low.bit_length() - 1, Q)
                out[q][d] = (0,)
                R ^= low
            return out
        after, known = self._after_all, self._joint
        covered = 0
        stack = [((self._identity,), mask, (1 << n) - 1, ())]
        while stack:
            F, m, left, prefix = stack.pop()
            if left == 0:
                common = -1
                for R in F:
                    common &= R
                new = common & ~covered
                covered |= new
                while new:
                    low = new & -new
                    q, d = divmod(low.bit_length() - 1, Q)
                    out[q][d] = prefix
                    new ^= low
                continue
            _push_orders(stack, known, after, ids, F, m, left, prefix)
        return out

    def _search_chains(self, q: int, mask: int, chains: list[tuple[tuple[int, int], ...]]) -> dict[int, tuple]:
        """:meth:`_search` when every action's crossings have one interleaving: each order reads one word, so
        the family of subsets is a single subset throughout."""
        out: dict[int, tuple[int, ...]] = {}
        n = len(chains)
        delta, known = self.delta, self._delta
        stack = [(1 << q, mask, (1 << n) - 1, ())]
        while stack:
            S, m, left, prefix = stack.pop()
            if left == 0:
                d = 0
                while S:
                    if S & 1:
                        out.setdefault(d, prefix)
                    S >>= 1
                    d += 1
                continue
            for i in range(n - 1, -1, -1):
                if left >> i & 1:
                    chain = chains[i]
                    S2 = S
                    for k in range(len(chain) - 1):
                        keep, put = chain[k]
                        letter = m & keep | put
                        x = known.get((S2, letter))
                        S2 = delta(S2, letter) if x is None else x
                    if S2:
                        keep, put = chain[-1]
                        stack.append((S2, m & keep | put, left & ~(1 << i), prefix + (i,)))
        return out

    def _successors_key(self, q: int, mask: int, sig: tuple) -> dict[int, tuple[int, ...]]:
        return self._orders(q, self._step_id(mask, sig))

    def successors(self, q: int, s: State, t: State) -> dict[int, tuple[Action, ...]]:
        """NBA states q' of product edges (s, q) → (s', q') (s → t assumed a TS transition), each with an
        execution order of the step's region-changing actions that reaches it for every interleaving."""
        mask, sig, vis = self.key(s, t)
        rows = self._successors_key(q, mask, sig)
        acts = region_changing(self.ts.actions(s, t))
        return {d: self._full_order(acts, vis, o) for d, o in rows.items()}

    def matrix(self, s: State, t: State) -> np.ndarray:
        """``M[q, q']``: is (s, q) → (t, q') a product edge (s → t assumed a TS transition)?"""
        return self._full_matrix(self.step_id(s, t))

    def rows(self, s: State, t: State, qs) -> np.ndarray:
        """``M[qs]`` of :meth:`matrix`, computing only the rows asked for."""
        qs = np.asarray(qs, dtype=np.int64)
        return self.step_rows(np.full(len(qs), self.step_id(s, t), dtype=np.int64), qs)

    def step_rows(self, sids: np.ndarray, qs: np.ndarray) -> np.ndarray:
        """Row ``qs[r]`` of the matrix of step ``sids[r]`` (:meth:`step_id`) for every r, computing only those."""
        flat = sids * self.Q + qs
        at = self._row_at[flat]
        if (at < 0).any():
            for f in flat[at < 0].tolist():
                if self._row_at[f] < 0:
                    self._add_row(f)
            at = self._row_at[flat]
        return self._row_store[at]

    def step_targets(self, sid: int, q: int):
        """The NBA states of row q of step ``sid`` (:meth:`step_rows`), as the keys of a mapping."""
        return self._orders(q, sid)

    def _add_row(self, f: int) -> None:
        """Store row f = sid·Q + q, with every other row of step sid whose orders are known by then."""
        Q = self.Q
        sid, q = divmod(f, Q)
        self._orders(q, sid)
        orders, base = self._step_orders[sid], sid * Q
        new = [x for x in range(Q) if orders[x] is not None and self._row_at[base + x] < 0]
        k = self._num_rows
        while k + len(new) > len(self._row_store):
            self._row_store = np.concatenate([self._row_store, np.zeros_like(self._row_store)])
        cells = [(k + i) * Q + d for i, x in enumerate(new) for d in orders[x]]
        self._row_store.reshape(-1)[cells] = True
        self._row_at[[base + x for x in new]] = np.arange(k, k + len(new))
        self._num_rows = k + len(new)

    def _full_matrix(self, sid: int) -> np.ndarray:
        M = self._full.get(sid)
        if M is None:
            M = self._full[sid] = self.step_rows(np.full(self.Q, sid, dtype=np.int64), np.arange(self.Q))
        return M

    def matrix_for(self, mask: int, sig: tuple) -> np.ndarray:
        return self._full_matrix(self._step_id(mask, sig))

    # ------------------------------------------------------------------------------------ some word
    def _some_action(self, S0: int, S1: int, mask: int, cross: tuple) -> tuple[int, int]:
        """NBA states after one action's crossings over *some* interleaving, from the states S0 (no
        accepting state passed yet) and S1 (one passed): the union over the crossing lattice."""
        events, pre = _events(cross)
        n = len(events)
        acc = self._acc
        fam = {0: (S0, S1)}
        masks = {0: mask}
        for D in range(1 << n):
            cur = fam.get(D)
            if cur is None:
                continue
            letter = masks[D]
            T0 = self.delta(cur[0], letter)
            nxt = (T0 & ~acc, (T0 & acc) | self.delta(cur[1], letter))
            for i in range(n):
                if not D >> i & 1 and D & pre[i] == pre[i]:
                    D2 = D | 1 << i
                    old = fam.get(D2, (0, 0))
                    fam[D2] = (old[0] | nxt[0], old[1] | nxt[1])
                    masks[D2] = _apply(letter, events[i])
        return fam[(1 << n) - 1]

    def some_matrix_for(self, mask: int, sig: tuple) -> tuple[np.ndarray, np.ndarray]:
        """The over-approximation of a step: ``R[q, q']`` iff *some* order of the visible actions and some
        crossing interleaving takes the NBA from q to q'; ``A[q, q']`` iff one of those runs passes an
        accepting state inside the step (after any of its letters).  Every executed word
        of a TS run has an NBA run through these edges, so a product over them without an accepting cycle
        (an accepting node or an ``A`` edge on a cycle) proves that no execution satisfies the task."""
        key = (mask, sig)
        hit = self._some.get(key)
        if hit is not None:
            return hit
        Q = self.Q
        R = np.zeros((Q, Q), dtype=bool)
        A = np.zeros((Q, Q), dtype=bool)
        if not sig:
            for q in range(Q):
                R[q, self.nba.successors(q, mask)] = True
            self._some[key] = (R, A)
            return R, A
        n = len(sig)
        after = [mask] * (1 << n)  # the label once the actions of a subset are done (order-independent)
        for done in range(1, 1 << n):
            i = (done & -done).bit_length() - 1
            m = after[done & ~(1 << i)]
            for c in sig[i]:
                if c.leave >= 0:
                    m &= ~(1 << c.leave)
                if c.enter >= 0:
                    m |= 1 << c.enter
            after[done] = m
        for q in range(Q):
            G = {0: (1 << q, 0)}
            for done in range(1 << n):
                cur = G.get(done)
                if cur is None or cur == (0, 0):
                    continue
                for i in range(n):
                    if not done >> i & 1:
                        got = self._some_action(cur[0], cur[1], after[done], sig[i])
                        old = G.get(done | 1 << i, (0, 0))
                        G[done | 1 << i] = (old[0] | got[0], old[1] | got[1])
            S0, S1 = G.get((1 << n) - 1, (0, 0))
            for d in range(Q):
                if (S0 | S1) >> d & 1:
                    R[q, d] = True
                if S1 >> d & 1:
                    A[q, d] = True
        self._some[key] = (R, A)
        return R, A

    def some_matrix(self, s: State, t: State) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`some_matrix_for` of the step s → t."""
        mask, sig = self.signature(s, t)
        return self.some_matrix_for(mask, sig)

    def visible(self, X: np.ndarray, Y) -> np.ndarray:
        """``vis[r]``: does the step X[r] → Y[r] (or the reverse) move a body across a rim AP_φ mentions?
        ``Y`` is one state or one row per row of X.  Steps without such a crossing read only their source
        label (the paper's product)."""
        n_ent, idx = len(self._entities), self._entities
        A = np.asarray(X)[:, :n_ent]
        B = np.asarray(Y, dtype=np.int64)[..., :n_ent]  # one state broadcasts over the rows
        seen = self.entity_region[idx, A] | self.entity_region[idx, B]
        return ((A != B) & seen).any(axis=1)

    @staticmethod
    def _full_order(acts: list[Action], vis: list[Action], order: tuple[int, ...]) -> tuple[Action, ...]:
        """The region-changing actions in canonical order with the visible ones permuted into ``order``."""
        seq = iter(vis[i] for i in order)
        vis_set = set(vis)
        return tuple(next(seq) if a in vis_set else a for a in acts)

    def order(self, s: State, q: int, t: State, q2: int) -> tuple[Action, ...] | None:
        """All actions of s → t in execution order (releases, grasps, then the region-changing actions in an
        order reaching q2 from q for every interleaving), or None if there is none."""
        o = self.successors(q, s, t).get(q2)
        if o is None:
            return None
        acts = self.ts.actions(s, t)
        return tuple(a for a in acts if not isinstance(a, (Navigate, Transport))) + o

    def reached(self, S: int, s: State, t: State, order: Sequence[Action]) -> int:
        """NBA states (mask) reached from the set S for EVERY interleaving of the step s → t executed in
        ``order`` (intersection over the interleavings)."""
        mask, _, _ = self.key(s, t)
        vis = [c for a in region_changing(order) if (c := self.crossings(a))]
        if not vis:
            return self.delta(S, mask)
        F = frozenset([S])
        for c in vis:
            F, mask = self._after_action(F, mask, c)
        common = -1
        for T in F:
            common &= T
        return common

    def check_plan(self, formula: Formula, steps: Sequence[tuple[State, State, Sequence[Action]]],
                   loop_start: int) -> bool:
        """:func:`check_plan_words` of a lasso of steps (source, target, actions in execution order)."""
        return check_plan_words(self.ts, formula, steps, loop_start)

    def step_words(self, s: State, t: State, order: Sequence[Action]) -> Iterator[list[int]]:
        """Every word (projected letters) that executing s → t in ``order`` may produce."""
        m0 = self.ts.label_mask(s) & self.relevant
        vis = [c for a in region_changing(order) if (c := self.crossings(a))]
        if not vis:
            yield [m0]
            return

        def rec(k: int, mask: int, word: list) -> Iterator[list[int]]:
            if k == len(vis):
                yield list(word)
                return
            for seq in interleavings(vis[k]):
                m, w = mask, list(word)
                for ev in seq:
                    w.append(m)
                    m = _apply(m, ev)
                yield from rec(k + 1, m, w)

        yield from rec(0, m0, [])


# ---------------------------------------------------------------------------------------- plan words
def plan_word_graph(ts: TransitionSystem, relevant: int, steps: Sequence[tuple[State, State, Sequence[Action]]],
                    loop_start: int) -> tuple[list[tuple[int, int, int]], int]:
    """The graph of every word executing ``steps`` may produce: positions are nodes, an edge (u, v, letter)
    reads one letter; step k starts at node k (its crossing lattices get fresh nodes) and the last step
    loops back to node ``loop_start`` (the first suffix step).  Returns (edges, number of nodes)."""
    n_steps = len(steps)
    edges: list[tuple[int, int, int]] = []
    nodes = n_steps
    for k, (s, _t, order) in enumerate(steps):
        end = k + 1 if k + 1 < n_steps else loop_start
        mask = ts.label_mask(s) & relevant
        vis = [c for a in region_changing(order) if (c := crossings(ts, relevant, a))]
        if not vis:
            edges.append((k, end, mask))
            continue
        start = k
        for i, cross in enumerate(vis):
            events, pre = _events(cross)
            n = len(events)
            full = (1 << n) - 1
            ids = {0: start}
            last = i == len(vis) - 1
            masks = {0: mask}
            for D in range(1 << n):
                if D not in ids:
                    continue
                for j in range(n):
                    if not D >> j & 1 and D & pre[j] == pre[j]:
                        D2 = D | 1 << j
                        if D2 not in ids:
                            if D2 == full and last:
                                ids[D2] = end
                            else:
                                ids[D2] = nodes
                                nodes += 1
                            masks[D2] = _apply(masks[D], events[j])
                        edges.append((ids[D], ids[D2], masks[D]))
            start, mask = ids[full], masks[full]
    return edges, nodes


def check_plan_words(ts: TransitionSystem, formula: Formula, steps: Sequence[tuple[State, State, Sequence[Action]]],
                     loop_start: int) -> bool:
    """Does every word of :func:`plan_word_graph` satisfy ``formula``?  (No accepting lasso of the word
    graph times the NBA of ¬φ, translated afresh: independent of the planner's NBA run.)"""
    relevant = relevant_mask(ts, formula)
    edges, n = plan_word_graph(ts, relevant, steps, loop_start)
    return words_satisfy(ts.propositions, formula, edges, n)


def words_satisfy(propositions: Sequence[str], formula: Formula, edges: Sequence[tuple[int, int, int]], n: int,
                  start: int = 0) -> bool:
    """Does every infinite path of the word graph (``n`` nodes, edges (u, v, letter)) from ``start`` satisfy
    ``formula``?  (Model check against a fresh NBA of ¬φ.)"""
    neg = translate(Not(formula)).with_ap(propositions)
    P = neg.num_states
    rows, cols = [], []
    for u, v, letter in edges:
        for p in range(P):
            for p2 in neg.successors(p, letter):
                rows.append(u * P + p)
                cols.append(v * P + p2)
    size = n * P
    g = csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(size, size))
    reach = np.zeros(size, dtype=bool)
    reach[breadth_first_order(g, start * P + neg.initial, directed=True, return_predecessors=False)] = True
    _, comp = connected_components(g, directed=True, connection="strong")
    for x in np.flatnonzero(reach):
        if int(x) % P not in neg.accepting:
            continue
        same = comp == comp[x]
        lo, hi = g.indptr[x], g.indptr[x + 1]
        if np.any(same[g.indices[lo:hi]]):  # x lies on a cycle of its component
            return False
    return True


class SourceWords:
    """The paper's reading (one letter per step: the source state's label, projected on AP_φ) with the
    interface of :class:`ExecutedWords`, for transition systems whose steps pass through no other label
    (:class:`~mrodrake.planning.graph.GraphTS`)."""

    def __init__(self, ts, nba: NBA, relevant: int):
        if tuple(nba.ap) != tuple(ts.propositions):
            raise ValueError("the NBA must be over the TS propositions (use nba.with_ap(ts.propositions))")
        self.ts, self.nba, self.relevant = ts, nba, int(relevant)
        self.Q = nba.num_states
        self._matrix: dict[int, np.ndarray] = {}

    def letter(self, s: State) -> int:
        return self.ts.label_mask(s) & self.relevant

    def delta(self, S: int, letter: int) -> int:
        out, q = 0, 0
        while S >> q:
            if S >> q & 1:
                for d in self.nba.successors(q, letter):
                    out |= 1 << d
            q += 1
        return out

    def matrix_for(self, mask: int, sig: tuple = ()) -> np.ndarray:
        M = self._matrix.get(mask)
        if M is None:
            M = np.zeros((self.Q, self.Q), dtype=bool)
            for q in range(self.Q):
                M[q, self.nba.successors(q, mask)] = True
            self._matrix[mask] = M
        return M

    def matrix(self, s: State, t: State) -> np.ndarray:
        return self.matrix_for(self.letter(s))

    def rows(self, s: State, t: State, qs) -> np.ndarray:
        return self.matrix_for(self.letter(s))[qs]

    def visible(self, X: np.ndarray, Y) -> np.ndarray:
        return np.zeros(len(X), dtype=bool)

    def successors(self, q: int, s: State, t: State) -> dict[int, tuple]:
        acts = self.ts.actions(s, t)
        return {d: acts for d in self.nba.successors(q, self.letter(s))}

    def order(self, s: State, q: int, t: State, q2: int) -> tuple | None:
        return self.ts.actions(s, t) if q2 in self.nba.successors(q, self.letter(s)) else None

    def reached(self, S: int, s: State, t: State, order: Sequence) -> int:
        return self.delta(S, self.letter(s))

    def check_plan(self, formula: Formula, steps: Sequence[tuple[State, State, Sequence]], loop_start: int) -> bool:
        """Does the lasso of source labels satisfy ``formula``?"""
        n = len(steps)
        edges = [(k, k + 1 if k + 1 < n else loop_start, self.ts.label_mask(s) & relevant_mask(self.ts, formula))
                 for k, (s, _, _) in enumerate(steps)]
        return words_satisfy(self.ts.propositions, formula, edges, n)


def words_for(ts, nba: NBA, relevant: int):
    """The word semantics of a transition system: :class:`SourceWords` for those that read source labels
    (``reads_source_label``, the graph TS), else :class:`ExecutedWords`."""
    return (SourceWords if getattr(ts, "reads_source_label", False) else ExecutedWords)(ts, nba, relevant)
