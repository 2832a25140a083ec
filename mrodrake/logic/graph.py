"""Graph search over successor maps (lists, dicts or :class:`LazySucc`): breadth-first reachability and
strongly connected components by Tarjan's algorithm ("Depth-first search and linear graph algorithms",
SIAM J. Comput. 1(2), 1972), iterative."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

__all__ = ["LazySucc", "reachable", "sccs"]


class LazySucc:
    """Mapping-like successor function that records what it computed in ``store``."""

    def __init__(self, store: dict, fn):
        self.store = store
        self.fn = fn

    def __getitem__(self, v):
        r = self.store.get(v)
        if r is None:
            r = self.store[v] = self.fn(v)
        return r


def reachable(starts: Iterable, succ) -> list:
    """The nodes reachable from ``starts`` (included), in breadth-first order."""
    seen = set()
    order = []
    for s in starts:
        if s not in seen:
            seen.add(s)
            order.append(s)
    head = 0
    while head < len(order):
        v = order[head]
        head += 1
        for w in succ[v]:
            if w not in seen:
                seen.add(w)
                order.append(w)
    return order


def sccs(nodes: Sequence, succ) -> list[list]:
    """Tarjan's strongly connected components (iterative), successors' components first."""
    index: dict = {}
    low: dict = {}
    on_stack: set = set()
    stack: list = []
    out: list[list] = []
    counter = 0
    for root in nodes:
        if root in index:
            continue
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(succ[root]))]
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(succ[w])))
                    advanced = True
                    break
                if w in on_stack and index[w] < low[v]:
                    low[v] = index[w]
            if advanced:
                continue
            work.pop()
            if work:
                u = work[-1][0]
                if low[v] < low[u]:
                    low[u] = low[v]
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                out.append(comp)
    return out
