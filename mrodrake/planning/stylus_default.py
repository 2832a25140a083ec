"""The default problem of the public STyLuS* code (kantaros/STyLuS_star, ``functions/DefineInputs.m`` and
``functions/createFTS.m``), rebuilt as a :class:`~mrodrake.planning.graph.GraphTS`.

* One random TS shared by 100 robots: 1,000 states at uniform positions in [1, 1000]², a self-loop at every
  state, and from every state 14 uniformly drawn states (with repetition) joined to it both ways (average
  degree ≈ 28); the cost of an edge is the Euclidean distance of its endpoints.  Our generator is a seeded
  numpy one, so the graphs differ from MATLAB's but are drawn from the same distribution.
* Robot r starts at state r (r = 1..100).
* Predicates p1..p8 as in ``DefineInputs.m`` (robot -> TS states, 1-based); p6 is an OR, the others ANDs.
  One state listed for p6 (1010) does not exist in a 1,000-state TS and is left out (it can never hold).
* Task ``G(p1 -> X(!p1 U p2)) & GF p1 & GF p3 & GF p4 & (!p1 U p5) & G !p6 & F(p7 | p8) & GF p5``.

The product has 1000^100 × |Q| ≈ 10^301 states.  Reference (MATLAB, first feasible plan, authors' machine):
NBA 0.21 s with ltl2ba (21 states), pruning 0.08 s, prefix 33.3 s, suffix 4.5 s.
"""

from __future__ import annotations

import numpy as np

from mrodrake.planning.graph import GraphPlanning, GraphTS, graph_matrix

TASK = "G(p1 -> X(!p1 U p2)) & GF p1 & GF p3 & GF p4 & (!p1 U p5) & G !p6 & F(p7 | p8) & GF p5"
STATES = 1000
ROBOTS = 100
DEGREE = 28
#: Published times of the MATLAB code (seconds) and its NBA size.
REFERENCE = {"nba_seconds": 0.214, "prune_seconds": 0.083, "prefix_seconds": 33.27, "suffix_seconds": 4.52,
             "nba_states": 21}

#: proposition -> (mode, {robot: [TS states]}), 1-based as in DefineInputs.m
PREDICATES = {
    "p1": ("all", {4: [720, 340], 3: [110, 330], 1: [110, 980], 2: [210], 5: [172], 6: [10], 7: [107], 8: [501],
                   9: [104], 10: [71], 11: [900, 800], 12: [11]}),
    "p2": ("all", {12: [191], 13: [101], 14: [110], 15: [20], 16: [100], 17: [419], 18: [770], 19: [990],
                   20: [500], 21: [920], 22: [77], 23: [820], 24: [43], 25: [100], 26: [210], 27: [710],
                   28: [890], 29: [581]}),
    "p3": ("all", {29: [201], 30: [950], 31: [29], 32: [63], 33: [391], 34: [265], 35: [827], 36: [738],
                   37: [661], 38: [562], 39: [489], 40: [111], 41: [171], 42: [320], 43: [21], 44: [3],
                   45: [105], 46: [801], 47: [199], 48: [101], 49: [770], 50: [690], 51: [44]}),
    "p4": ("all", {52: [34], 53: [350], 54: [390], 55: [430], 56: [510], 57: [155], 58: [157], 59: [180],
                   60: [1], 61: [620], 62: [890], 63: [911], 64: [974], 65: [112], 66: [191], 67: [232],
                   68: [252], 69: [281], 70: [178], 71: [229], 72: [373], 73: [591], 74: [548]}),
    "p5": ("all", {74: [841], 75: [732], 76: [409], 77: [931], 78: [510], 79: [651], 80: [167], 81: [178],
                   82: [640], 83: [221], 84: [905], 85: [111], 86: [675], 87: [312], 88: [215], 89: [229],
                   90: [607], 91: [800], 92: [911], 93: [982], 94: [710], 95: [719], 96: [772]}),
    "p6": ("any", {97: [7, 183, 850, 1010], 98: [650, 777, 888, 999, 111, 222, 333, 444, 555]}),
    "p7": ("all", {96: [2], 97: [110], 98: [831]}),
    "p8": ("all", {99: [254], 100: [690]}),
}


def random_fts(seed: int, states: int = STATES,
               degree: int = DEGREE) -> tuple[np.ndarray, list[tuple[int, int, float]]]:
    """(positions, undirected edges (u, v, Euclidean length)) of a createFTS-style random TS (0-based)."""
    rng = np.random.default_rng(seed)
    pos = 1.0 + (states - 1.0) * rng.random((states, 2))
    targets = rng.integers(0, states, size=(states, degree // 2))
    edges = []
    for u in range(states):
        for v in targets[u]:
            v = int(v)
            edges.append((u, v, float(np.hypot(*(pos[u] - pos[v])))))
    return pos, edges


def stylus_default_ts(seed: int = 0, robots: int = ROBOTS, states: int = STATES) -> GraphTS:
    """The default STyLuS* problem on a random TS drawn with ``seed`` (the task is :data:`TASK`)."""
    _, edges = random_fts(seed, states)
    m = graph_matrix(states, edges, undirected=True, self_loops=True)
    props = {}
    for name, (mode, clauses) in PREDICATES.items():
        props[name] = (mode, {r - 1: [v - 1 for v in vs if v <= states] for r, vs in clauses.items() if r <= robots})
    return GraphTS(f"stylus_default_s{seed}", [f"r{i + 1}" for i in range(robots)],
                   [("fts", [str(v + 1) for v in range(states)], m)], [0] * robots, list(range(robots)), props,
                   GraphPlanning(seed=seed), TASK)
