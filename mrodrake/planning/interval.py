"""The interval over-approximation of executed words on the explicit TS: fast proofs of unsatisfiability.

Executing a TS step s → t, the NBA reads the source label L(s) first and then, while bodies cross rims, labels
in which every moving body is in its source region, in its destination or between them
(:mod:`mrodrake.planning.semantics`).  Projected on AP_φ every such letter ℓ lies in the *interval*
L(s) ∧ L(t) ⊆ ℓ ⊆ L(s) ∨ L(t).  The interval product lets a step read L(s) and then any number of letters of
its interval in any order (a step without a visible crossing reads L(s) once, as in the paper): it admits
every executed word of every TS run, forgets only the order of the crossings, and needs no crossing
lattices, so it is built with array operations for millions of TS transitions.  No reachable cycle through
an accepting state (at a step boundary or inside a step) proves that no execution satisfies the task.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components

from mrodrake.logic.nba import NBA
from mrodrake.ts import ExplicitTS, TransitionSystem

#: Label pairs per chunk of the product construction (bounds its temporaries).
CHUNK = 200_000


def _compact(relevant: int) -> list[int]:
    return [b for b in range(relevant.bit_length()) if relevant >> b & 1]


def interval_accepts(ts: TransitionSystem, nba: NBA, relevant: int, ets: ExplicitTS) -> bool:
    """Does the interval product (module docstring) of ``ets`` and ``nba`` (over ``ts.propositions``) have a
    reachable accepting cycle?  False proves the task unsatisfiable."""
    bits = _compact(relevant)
    if len(bits) > 63:
        return True  # labels do not fit one machine word: no proof
    S, Q = ets.num_states, nba.num_states
    N, M, K = ts.N, ts.M, ts.K
    code = np.zeros((N + M, K), dtype=np.uint64)
    for c, b in enumerate(bits):
        e, k = divmod(b, K)
        code[e, k] = np.uint64(1) << np.uint64(c)
    pos = ets.states[:, : N + M].astype(np.int64)
    lab = np.zeros(S, dtype=np.uint64)
    for e in range(N + M):
        lab |= code[e, pos[:, e]]

    def compact(x: int) -> int:
        return sum(1 << c for c, b in enumerate(bits) if x >> b & 1)

    cubes = [(q, d, compact(p), compact(n)) for q, row in enumerate(nba.edges) for g, d in row for p, n in g]
    if not cubes:
        return False
    cq = np.array([c[0] for c in cubes], dtype=np.int64)
    cd = np.array([c[1] for c in cubes], dtype=np.int64)
    cp = np.array([c[2] for c in cubes], dtype=np.uint64)
    cn = np.array([c[3] for c in cubes], dtype=np.uint64)
    acc = np.zeros(Q, dtype=bool)
    acc[list(nba.accepting)] = True
    fd = acc[cd].astype(np.int64)
    src = np.repeat(np.arange(S, dtype=np.int64), np.diff(ets.indptr))
    dst = ets.targets.astype(np.int64)
    labels, lid = np.unique(lab, return_inverse=True)
    lid = lid.ravel().astype(np.int64)
    pairs, inv = np.unique(lid[src] * len(labels) + lid[dst], return_inverse=True)
    inv = inv.ravel()
    ls, ld = labels[pairs // len(labels)], labels[pairs % len(labels)]
    spans, span_of = np.unique(np.stack([ls & ld, ls | ld], axis=1), axis=0, return_inverse=True)
    span_of = span_of.ravel()
    n2 = 2 * Q  # automaton with a flag: state 2q + f, f = an accepting state was passed in this step

    def letters(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """(len(lo), 2Q, 2Q) moves on one letter ℓ with lo ⊆ ℓ ⊆ hi."""
        ok = ((cp[None, :] & ~hi[:, None]) == 0) & ((cn[None, :] & lo[:, None]) == 0)
        out = np.zeros((len(lo), n2, n2), dtype=np.float32)
        kk, cc = np.nonzero(ok)
        out[kk, 2 * cq[cc], 2 * cd[cc] + fd[cc]] = 1.0
        out[kk, 2 * cq[cc] + 1, 2 * cd[cc] + 1] = 1.0
        return out

    first = letters(labels, labels)  # the source label, read once
    closure = np.zeros((len(spans), n2, n2), dtype=np.float32)  # any number of letters of the interval
    for lo_k in range(0, len(spans), CHUNK // 4):
        part = spans[lo_k: lo_k + CHUNK // 4]
        X = letters(part[:, 0], part[:, 1]) + np.eye(n2, dtype=np.float32)[None]
        for _ in range(int(np.ceil(np.log2(n2)))):
            X = (np.matmul(X, X) > 0).astype(np.float32)
        closure[lo_k: lo_k + CHUNK // 4] = X
    moves = np.zeros((len(pairs), n2, n2), dtype=bool)
    vis = ls != ld
    for lo_k in range(0, len(pairs), CHUNK // 4):
        sl = slice(lo_k, lo_k + CHUNK // 4)
        f1 = first[pairs[sl] // len(labels)]
        moves[sl] = np.where(vis[sl, None, None], np.matmul(f1, closure[span_of[sl]]) > 0, f1 > 0)
    reach = moves[:, 0::2, 0::2] | moves[:, 0::2, 1::2]
    flag = moves[:, 0::2, 1::2]

    def expand(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Product edges (rows, cols) of every TS transition from the per-pair NBA moves ``m``."""
        p, q, q2 = np.nonzero(m)
        ptr = np.concatenate([[0], np.cumsum(np.bincount(p, minlength=len(m)))])
        count = ptr[inv + 1] - ptr[inv]
        total = int(count.sum())
        e = np.repeat(np.arange(len(inv), dtype=np.int64), count)
        k = np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(count) - count, count) + np.repeat(ptr[inv], count)
        return src[e] * Q + q[k], dst[e] * Q + q2[k]

    rows, cols = expand(reach)
    frows, fcols = expand(flag)
    g = sp.csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(S * Q, S * Q))
    order = breadth_first_order(g, nba.initial, directed=True, return_predecessors=False)
    seen = np.zeros(S * Q, dtype=bool)
    seen[order] = True
    _, comp = connected_components(g, directed=True, connection="strong")
    on = seen[frows] & (comp[frows] == comp[fcols])
    return bool(on.any())
